"""Shared scene set-up for the vision tests: one distorted 640x480 camera above the patch."""

from __future__ import annotations

import numpy as np
import pytest

from umbra.modules.calib.camera_model import Intrinsics
from umbra.modules.vision.scene import SceneRenderer, camera_looking_down

INTRINSICS = Intrinsics(fx=600.0, fy=600.0, skew=0.0, u0=320.0, v0=240.0, width=640, height=480)
#: OpenCV's [k1, k2, p1, p2, k3].
DISTORTION = np.array([-0.12, 0.03, 0.001, -0.0007, 0.0])
#: The camera 0.22 m above the patch (patch plane at z = 0.03 m), looking straight down.
T_WORLD_CAMERA = camera_looking_down((0.0, 0.0, 0.03), 0.22)
#: World metres per image pixel at the patch's depth (0.22 m / 600 px focal length).
METRES_PER_PIXEL = 0.22 / 600.0


@pytest.fixture(scope="session")
def renderer() -> SceneRenderer:
    return SceneRenderer(INTRINSICS, DISTORTION)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20240611)
