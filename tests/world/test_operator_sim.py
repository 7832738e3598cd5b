"""OperatorSim clicks on the patch once it has been seen for its delay, and says when."""

from __future__ import annotations

import numpy as np
import pytest

from umbra.connectors.commands import SeedShape
from umbra.connectors.messages import Contour
from umbra.modules.world.operator_sim import OperatorSim
from umbra.runtime.harness import ModuleHarness

DT = 0.05


def _square(cx: float, cy: float, half: float = 20.0) -> Contour:
    points = np.array(
        [
            [cx - half, cy - half],
            [cx + half, cy - half],
            [cx + half, cy + half],
            [cx - half, cy + half],
        ]
    )
    return Contour(
        vertices=points,
        centroid=np.array([cx, cy]),
        area=(2 * half) ** 2,
        orientation=0.0,
        axes=np.array([2 * half, 2 * half]),
    )


def test_clicks_near_the_centroid_after_the_delay_and_reports_when() -> None:
    params = {"click_delay_s": 0.22, "click_noise_px": 1.0}
    with ModuleHarness(OperatorSim, params) as h:
        h.step(dt=DT)  # nothing seen yet: no click
        h.step(dt=DT)
        assert h.outputs("seed") == []
        for _ in range(10):
            h.push("truth", _square(320.0, 240.0))
            h.step(dt=DT)
        seeds = h.outputs("seed")
        assert len(seeds) == 1  # one click, never repeated
        assert seeds[0].shape == SeedShape.POINT
        assert np.linalg.norm(seeds[0].uv - [320.0, 240.0]) < 5.0
        summary = h.module.summary()
    # first step at DT, patch first seen at 3 DT, clicked at the first step 0.22 s after that (8 DT)
    assert summary["clicked_after_s"] == pytest.approx(7 * DT, abs=1e-6)
    assert summary["clicked_at_s"] == pytest.approx(8 * DT, abs=1e-6)
    assert summary["click_uv"] == [round(float(v), 2) for v in seeds[0].uv]


def test_no_patch_no_click() -> None:
    with ModuleHarness(OperatorSim) as h:
        for _ in range(20):
            h.push("truth", _square(320.0, 240.0, half=0.0))  # empty outline: area 0
            h.step(dt=DT)
        assert h.outputs("seed") == []
        assert h.module.summary()["clicked_after_s"] is None
