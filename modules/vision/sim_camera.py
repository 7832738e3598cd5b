"""The simulated wrist camera as a device: renders the patch scene for a camera model and pose.

Keeps one :class:`~modules.vision.scene.SceneRenderer` per camera model (building one solves
the distortion maps, about a tenth of a second at 640x480), so a camera whose model changes
(a zoom) costs that each time its intrinsics change.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from modules.vision.lighting import Lighting
from modules.vision.projection import CameraIntrinsics, Distortion
from modules.vision.scene import RenderedFrame, Scene, SceneRenderer


@dataclass(frozen=True)
class CameraSpec:
    """Intrinsics (pixels) and distortion [k1, k2, p1, p2, k3] of the simulated camera."""

    intrinsics: CameraIntrinsics
    distortion: Distortion

    @classmethod
    def from_values(
        cls,
        fx: float,
        fy: float,
        skew: float,
        u0: float,
        v0: float,
        width: int,
        height: int,
        dist: ArrayLike,
    ) -> CameraSpec:
        coefficients = np.zeros(5)
        given = np.asarray(dist, dtype=float).ravel()
        if given.size not in (0, 4, 5):
            raise ValueError(f"distortion needs 4 or 5 coefficients, got {given.size}")
        coefficients[: given.size] = given
        return cls(
            CameraIntrinsics(
                float(fx), float(fy), float(skew), float(u0), float(v0), int(width), int(height)
            ),
            Distortion(*(float(c) for c in coefficients)),
        )


class SimulatedCamera:
    """Renders frames of a :class:`Scene` through the camera of the latest :class:`CameraSpec`."""

    def __init__(self) -> None:
        self._renderer: SceneRenderer | None = None
        self._spec: CameraSpec | None = None
        self.renderers_built = 0

    def render(
        self,
        spec: CameraSpec,
        scene: Scene,
        T_world_camera: NDArray[np.float64],
        lighting: Lighting,
        rng: np.random.Generator,
    ) -> RenderedFrame:
        """One frame with its ground truth (see :meth:`SceneRenderer.render`)."""
        if self._renderer is None or spec != self._spec:
            self._renderer = SceneRenderer(spec.intrinsics, spec.distortion)
            self._spec = spec
            self.renderers_built += 1
        return self._renderer.render(scene, T_world_camera, lighting, rng)
