"""Stated errors hold: the 95 % intervals of ``umbra calib fit`` (every parameter) and of the
pose tool's mount hold the simulated truth 95 % of the time (within 2 points) over fresh click
noise, with fixed seeds. The heavy Monte Carlo runs are ``slow``; a small run in the default
suite checks the sum of squared z-scores against its chi-square bounds."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

from umbra.modules.calib import pose_tool_synthetic as synthetic
from umbra.modules.calib.camera_model import Intrinsics, PinholeCamera
from umbra.modules.calib.pose_tool import solve_mount
from umbra.modules.calib.refine import calibrate
from umbra.modules.calib.rotations import rotation_from_vector, vector_from_rotation

TRUTH = Intrinsics(800.0, 800.0, 0.0, 320.0, 240.0)
R_TRUE = rotation_from_vector([0.1, -0.2, 0.05])
D_TRUE = np.array([0.05, -0.02, 1.0])
LENS = (-0.25, 0.1, 0.001, -0.0005)


def calibration_errors(fit) -> dict[str, float]:
    """Each fitted parameter's error against the truth, the rotation as a rotation vector about
    the fitted R (reference frame), as the standard errors state it."""
    camera = fit.camera
    got = dict(zip(("fx", "fy", "skew", "u0", "v0"), camera.intrinsics.as_array(), strict=True))
    got.update(zip(("k1", "k2", "p1", "p2"), camera.distortion[:4], strict=True))
    truth = dict(zip(("fx", "fy", "skew", "u0", "v0"), TRUTH.as_array(), strict=True))
    truth.update(zip(("k1", "k2", "p1", "p2"), LENS, strict=True))
    errors = {name: got[name] - truth[name] for name in truth}
    rotation = vector_from_rotation(R_TRUE @ camera.R.T)
    errors.update(zip(("rx", "ry", "rz"), rotation, strict=True))
    errors.update(zip(("dx", "dy", "dz"), camera.d - D_TRUE, strict=True))
    return errors


def calibration_z(
    runs: int, seed: int, points: int = 40, interval: bool = False
) -> dict[str, np.ndarray]:
    """Every parameter's error over its stated error (or over its 95 % half-width, with
    ``interval``) over ``runs`` refits of a rig of ``points`` points with 0.3 px noise."""
    box = ([-0.3, -0.25, -0.2], [0.3, 0.25, 0.2])
    X = np.random.default_rng(11).uniform(*box, (points, 3))
    lens = PinholeCamera(TRUTH, R_TRUE, D_TRUE, LENS)
    rng = np.random.default_rng(seed)
    z: dict[str, list[float]] = {}
    for _ in range(runs):
        fit = calibrate(X, lens.project(X) + rng.normal(0, 0.3, (points, 2)), distortion_terms=4)
        errors = calibration_errors(fit)
        stated = fit.interval_95() if interval else fit.standard_errors
        for name, value in stated.items():
            z.setdefault(name, []).append(errors[name] / value)
    return {name: np.array(values) for name, values in z.items()}


def mount_z(runs: int, seed: int, pixel_sigma: float | None) -> dict[str, np.ndarray]:
    """The pose tool's mount errors over its 95 % half-widths (``interval_95``), per
    parameter, over ``runs`` sets of 1 px clicks of one case (8 points, 3 PTU poses)."""
    rng = np.random.default_rng(seed)
    case = synthetic.random_case(rng, snapshots=3, points=8)
    truth = case.T_head_camera_true
    ratios: dict[str, list[float]] = {}
    for _ in range(runs):
        snapshots = synthetic.click_snapshots(case, 1.0, rng)
        result = solve_mount(snapshots, case.T_head_camera_nominal, pixel_sigma=pixel_sigma)
        mount = result.T_parent_child
        rotation = vector_from_rotation(truth[:3, :3] @ mount[:3, :3].T)
        errors = np.concatenate([rotation, truth[:3, 3] - mount[:3, 3]])
        for (name, half), error in zip(result.interval_95().items(), errors, strict=True):
            ratios.setdefault(name, []).append(error / half)
    return {name: np.array(values) for name, values in ratios.items()}


def test_calib_fit_errors_are_taken_at_the_fitted_rotation() -> None:
    """A small run: the sum of squared z-scores of every parameter (rotation included) lies
    within the chi-square bounds of its count (the errors about the DLT start's rotation, not
    the fitted one, stated rz 21 % too small)."""
    runs = 60
    low, high = chi2.ppf([0.005, 0.995], runs)
    for name, z in calibration_z(runs, seed=9).items():
        assert low < float(z @ z) < high, (name, float(z @ z) / runs)


def test_the_pose_tool_states_the_mount_covariance() -> None:
    rng = np.random.default_rng(3)
    case = synthetic.random_case(rng, snapshots=3, points=8)
    result = solve_mount(synthetic.click_snapshots(case, 1.0, rng), case.T_head_camera_nominal)
    assert result.covariance is not None and result.covariance.shape == (6, 6)
    assert np.allclose(result.covariance, result.covariance.T)
    assert np.all(np.linalg.eigvalsh(result.covariance) > 0.0)
    se = result.standard_errors
    # a few mrad and millimetres for 1 px clicks of points a metre away
    assert all(1e-5 < se[name] < 2e-2 for name in ("rx", "ry", "rz", "x", "y", "z")), se
    # noise estimated from 16 clicks (32 coordinates, 26 degrees of freedom): t, not 1.96
    assert result.noise_dof == 26.0
    assert result.interval_95()["x"] == pytest.approx(2.0555 * se["x"], rel=1e-3)


def test_the_mount_covariance_matches_a_perturbed_solve() -> None:
    """The mount's covariance is the solver's carried through the inverse: the mount moved by
    one standard error along a parameter changes the cost as the covariance predicts (the
    Gauss-Newton cost rises by sigma² at one standard error along an eigen-direction)."""
    rng = np.random.default_rng(5)
    case = synthetic.random_case(rng, snapshots=3, points=8)
    snapshots = synthetic.click_snapshots(case, 1.0, rng)
    result = solve_mount(snapshots, case.T_head_camera_nominal, pixel_sigma=1.0)
    assert result.covariance is not None
    values, vectors = np.linalg.eigh(result.covariance)
    cost0 = sum(float(np.sum(s.reprojection(result.T_parent_child) ** 2)) for s in snapshots)
    for value, vector in zip(values, vectors.T, strict=True):
        step = np.sqrt(value) * vector
        moved = result.T_parent_child.copy()
        moved[:3, :3] = rotation_from_vector(step[:3]) @ moved[:3, :3]
        moved[:3, 3] += step[3:]
        cost = sum(float(np.sum(s.reprojection(moved) ** 2)) for s in snapshots)
        assert cost - cost0 == pytest.approx(1.0, rel=0.05)


@pytest.mark.slow
@pytest.mark.untimed
def test_calib_fit_95_percent_intervals_hold_the_truth() -> None:
    """60 points at 0.3 px. (At 40 points the depth-focal valley bends: fx and dz hold the
    truth 92.5-93.5 % of the time, their z-scores spread 4-6 % wider than first order.)"""
    for name, ratio in calibration_z(800, seed=21, points=60, interval=True).items():
        coverage = 100.0 * float(np.mean(np.abs(ratio) < 1.0))
        assert 93.0 <= coverage <= 97.0, (name, coverage)


@pytest.mark.slow
@pytest.mark.untimed
@pytest.mark.parametrize("pixel_sigma", [None, 1.0])
def test_pose_tool_95_percent_intervals_hold_the_truth(pixel_sigma) -> None:
    for name, ratio in mount_z(800, seed=44, pixel_sigma=pixel_sigma).items():
        coverage = 100.0 * float(np.mean(np.abs(ratio) < 1.0))
        assert 93.0 <= coverage <= 97.0, (name, coverage)
