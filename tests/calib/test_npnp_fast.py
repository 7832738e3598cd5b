"""nPnP's fast path: starts ranked by cost, a run that enters a minimum already found stopped
there, EPnP left out on coplanar views. It must find what running every start to convergence
finds (the best minimum, and a rival that fits about as well), and on planar four-point targets
seen by 1, 2 or 4 cameras (fresh seeds, not those the solver was tuned on) the global minimum or
a warning naming the rival. The global minimum is found independently by Gauss-Newton from many
random rotations. Speed is measured in ``benchmarks/calib_bundle.py``, not here."""

from __future__ import annotations

import numpy as np
import pytest

from tests.calib.test_npnp_planar import CAMERA, lowest_cost, planar_scene
from umbra.modules.calib.camera_model import PinholeCamera
from umbra.modules.calib.npnp import (
    View,
    _gauss_newton,
    _prepare,
    _SameMinimum,
    _stack,
    _starts,
    solve_npnp,
)
from umbra.modules.calib.npnp_warnings import _angle_deg, _chi2_quantile
from umbra.modules.calib.rotations import rotation_from_vector, vector_from_rotation
from umbra.modules.calib.synthetic import TYPICAL_INTRINSICS, random_pose, ring_of_cameras


def rig_planar_scene(
    rng: np.random.Generator, cameras: int
) -> tuple[list[View], float, tuple[float, float, float]]:
    """One 4-point planar target (3-30 cm, tilted up to 75 deg, corners jittered in its plane)
    at the centre of a rig of ``cameras`` on an arc 0.3-4 m away with a 5-30 cm baseline,
    clicked with 0.2-2 px noise: ``(views, sigma, offset)``, ``offset`` a translation [m] for
    random starts that puts the target in front of every camera."""
    side = rng.uniform(0.03, 0.3)
    square = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * side / 2
    X = np.column_stack([square + rng.normal(0, 0.1 * side, (4, 2)), np.zeros(4)])
    while True:
        R = rotation_from_vector(rng.normal(size=3) * 2)
        if (R @ [0, 0, 1])[2] < -np.cos(np.radians(75)):
            break
    distance = rng.uniform(0.3, 4.0)
    baseline = rng.uniform(0.05, 0.3)
    rig = ring_of_cameras(cameras, distance, TYPICAL_INTRINSICS, spread=baseline / 2 / distance)
    d = rng.uniform(-0.1, 0.1, 3) * distance
    sigma = rng.uniform(0.2, 2.0)
    views = [View(c, X, c.project(X @ R.T + d) + rng.normal(0, sigma, (4, 2))) for c in rig]
    return views, sigma, (0.0, 0.0, 0.0)


def ring_scene(rng: np.random.Generator, cameras: int) -> tuple[list[View], float]:
    """4 points of a 30 cm cube per camera, cameras on a 2 m ring, 1 px noise."""
    rig: list[PinholeCamera] = ring_of_cameras(cameras, 2.0, spread=0.8)
    R, d = random_pose(rng, angle=0.5, offset=0.1)
    views = []
    for camera in rig:
        X = rng.uniform(-0.15, 0.15, (4, 3))
        views.append(View(camera, X, camera.project(X @ R.T + d) + rng.normal(0, 1.0, (4, 2))))
    return views, 1.0


def every_start_run_fully(views: list[View]) -> list[tuple[float, np.ndarray]]:
    """``(cost [px²], R)`` of Gauss-Newton run to convergence from every start the solver makes,
    with no start skipped and no run stopped early."""
    prepared = _prepare(views)
    stacked = _stack(prepared)
    minima = []
    for _, R0, d0 in _starts(prepared, None):
        try:
            R, _, r, _ = _gauss_newton(stacked, R0, d0, 100, 1e-12)
        except Exception:  # a start that fails says nothing about the minimum
            continue
        minima.append((float(r @ r), R))
    return minima


def apart_deg(R_a: np.ndarray, R_b: np.ndarray) -> float:
    """The angle [deg] of the rotation between two rotation matrices, exact near 0."""
    return float(np.degrees(np.linalg.norm(vector_from_rotation(R_a.T @ R_b))))


def test_a_run_that_enters_a_known_minimum_stops_there() -> None:
    views, _ = ring_scene(np.random.default_rng(5), 4)
    stacked = _stack(_prepare(views))
    solved = solve_npnp(views)
    R, d, r, _ = _gauss_newton(stacked, solved.R, solved.d, 100, 1e-12)
    start = rotation_from_vector([0.0, 0.15, 0.0]) @ R  # 8.6 deg off, in the same basin
    again, _, r_again, iterations = _gauss_newton(stacked, start, d, 100, 1e-12)
    assert iterations >= 3 and apart_deg(again, R) < 1e-4
    assert float(r_again @ r_again) == pytest.approx(float(r @ r), rel=1e-9)
    with pytest.raises(_SameMinimum):
        _gauss_newton(stacked, start, d, 100, 1e-12, known=[(R, d)])
    # a known minimum elsewhere does not stop it
    elsewhere = rotation_from_vector([0.0, 0.0, 1.0]) @ R
    stopped = _gauss_newton(stacked, start, d, 100, 1e-12, known=[(elsewhere, d)])
    assert apart_deg(stopped[0], R) < 1e-4


@pytest.mark.parametrize("kind", ["1 view planar", "2 cameras planar", "4 cameras", "2 cameras"])
def test_the_fast_path_finds_what_every_start_run_fully_finds(kind: str) -> None:
    rng = np.random.default_rng({"1 view planar": 41, "2 cameras planar": 42}.get(kind, 43))
    for _ in range(12):
        if kind == "1 view planar":
            X, pixels, sigma = planar_scene(rng, points=4)
            views = [View(CAMERA, X, pixels)]
        elif kind == "2 cameras planar":
            views, sigma, _ = rig_planar_scene(rng, 2)
        else:
            views, sigma = ring_scene(rng, int(kind[0]))
        result = solve_npnp(views, pixel_sigma=sigma)
        cost = float(sum(np.sum(r**2) for r in result.residuals))
        minima = sorted(every_start_run_fully(views), key=lambda m: m[0])
        best_cost, best_R = minima[0]
        assert cost <= best_cost * (1 + 1e-9) + 1e-12, (cost, best_cost)
        rivals = [
            m
            for m in minima[1:]
            if _angle_deg(m[1], best_R) > 2.0
            and (m[0] - best_cost) / sigma**2 < 0.9 * _chi2_quantile(0.95, 6)
        ]
        if rivals:  # a rival clearly inside the test's bound is named by the fast path too
            assert any("another pose" in w for w in result.warnings), (rivals, result.warnings)


def global_or_warned(scenes: int, seed: int, cameras: int, starts: int) -> tuple[int, int]:
    """(scenes of a 4-point planar target seen by ``cameras`` where the solution is the global
    minimum or a rival is named, scenes)."""
    rng = np.random.default_rng(seed)
    good = 0
    for _ in range(scenes):
        if cameras == 1:
            X, pixels, sigma = planar_scene(rng, points=4)
            views, offset = [View(CAMERA, X, pixels)], (0.0, 0.0, 1.0)
        else:
            views, sigma, offset = rig_planar_scene(rng, cameras)
        result = solve_npnp(views, pixel_sigma=sigma)
        cost = float(sum(np.sum(r**2) for r in result.residuals))
        best = lowest_cost(views, rng, starts, offset)
        rival = any("another pose" in w for w in result.warnings)
        good += cost <= best * (1 + 1e-6) + 1e-12 or rival
    return good, scenes


@pytest.mark.parametrize(("cameras", "scenes"), [(1, 16), (2, 8), (4, 8)])
def test_planar_four_point_targets_from_fresh_seeds(cameras: int, scenes: int) -> None:
    good, total = global_or_warned(scenes, seed=300 + cameras, cameras=cameras, starts=30)
    assert good == total


@pytest.mark.slow
@pytest.mark.untimed
@pytest.mark.timeout(600)  # tens of seconds of CPU; the wall time grows with the machine's load
@pytest.mark.parametrize(("cameras", "scenes"), [(1, 400), (2, 150), (4, 150)])
def test_planar_four_point_targets_over_many_fresh_scenes(cameras: int, scenes: int) -> None:
    good, total = global_or_warned(scenes, seed=400 + cameras, cameras=cameras, starts=60)
    assert good == total
