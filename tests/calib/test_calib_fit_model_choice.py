"""``umbra calib fit`` chooses the distortion model the data hold (tangential terms always,
radial terms by an F test), says why, and gives each parameter's standard error, checked by
Monte Carlo (the spread of refits over fresh noise), the truth being the simulated camera."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import chi2

from umbra.modules.calib.camera_model import Intrinsics, PinholeCamera
from umbra.modules.calib.model_choice import calibrate_choosing_distortion
from umbra.modules.calib.refine import calibrate
from umbra.modules.calib.rotations import rotation_from_vector
from umbra.runtime.cli.main import main

TRUTH = Intrinsics(800.0, 800.0, 0.0, 320.0, 240.0)


def camera(distortion=()) -> PinholeCamera:
    R = rotation_from_vector([0.1, -0.2, 0.05])
    return PinholeCamera(TRUTH, R, np.array([0.05, -0.02, 1.0]), distortion)


def rig(seed: int, n: int = 40) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.uniform([-0.3, -0.25, -0.2], [0.3, 0.25, 0.2], (n, 3))


def write_csv(path: Path, X: np.ndarray, uv: np.ndarray) -> None:
    rows = [
        f"{x:.9f},{y:.9f},{z:.9f},{u:.6f},{v:.6f}" for (x, y, z), (u, v) in zip(X, uv, strict=True)
    ]
    path.write_text("x,y,z,u,v\n" + "\n".join(rows) + "\n")


def fit_json(tmp_path: Path, X, uv, capsys, *extra: str) -> dict:
    write_csv(tmp_path / "pairs.csv", X, uv)
    assert main(["calib", "fit", str(tmp_path / "pairs.csv"), "--json", *extra]) == 0
    return json.loads(capsys.readouterr().out)


def test_undistorted_data_get_no_distortion_and_the_true_focal_length(tmp_path, capsys) -> None:
    # the case: 40 points, 0.3 px noise, a lens without distortion
    X = rig(0)
    uv = camera().project(X) + np.random.default_rng(100).normal(0, 0.3, (40, 2))
    out = fit_json(tmp_path, X, uv, capsys)
    assert out["distortion_model"] == "p1p2"
    assert "F test" in out["why"] and out["radial_test"]["p_value"] >= 0.01
    assert set(out["rms_px_by_model"]) == {"p1p2", "k1k2p1p2"}
    assert all(out["intrinsics"][k] == 0.0 for k in ("k1", "k2"))
    for term in ("p1", "p2"):  # fitted, and zero within their errors
        assert abs(out["intrinsics"][term]) < 3.0 * out["standard_errors"][term]
    fx, se = out["intrinsics"]["fx"], out["standard_errors"]["fx"]
    assert 0.3 < se < 5.0 and abs(fx - 800.0) < 3.0 * se
    # the report's four-term model, forced, trades k2 against the focal length
    forced = fit_json(tmp_path, X, uv, capsys, "--distortion", "k1k2p1p2")
    assert forced["distortion_model"] == "k1k2p1p2" and forced["why"] == "given by --distortion"


def test_choice_over_many_rigs() -> None:
    """No radial terms on undistorted rigs, radial terms on every distorted one, tangential
    terms always."""
    undistorted, distorted = 0, 0
    for seed in range(20):
        X = rig(seed)
        noise = np.random.default_rng(1000 + seed).normal(0, 0.3, (40, 2))
        bare = calibrate_choosing_distortion(X, camera().project(X) + noise)[1].chosen
        undistorted += bare == "p1p2"
        lens = camera([-0.25, 0.1, 0.0, 0.0])
        distorted += calibrate_choosing_distortion(X, lens.project(X) + noise)[1].chosen == (
            "k1k2p1p2"
        )
    assert undistorted >= 19 and distorted == 20


@pytest.mark.parametrize("sigma", [0.3, 0.5])
def test_real_tangential_terms_are_kept_and_the_principal_point_stays_honest(sigma) -> None:
    """A lens decentred by p1 0.0012, p2 -0.0008 (0.1-0.3 px at the rig's edge): the fit keeps
    p1 p2 at 0.3 and 0.5 px of noise, and the principal point stays within 3.3 of its stated
    errors on every rig (dropping the terms moves it further)."""
    lens = camera([-0.25, 0.1, 0.0012, -0.0008])
    for seed in range(12):
        X = rig(200 + seed)
        uv = lens.project(X) + np.random.default_rng(300 + seed).normal(0, sigma, (40, 2))
        fit, choice = calibrate_choosing_distortion(X, uv)
        assert choice.chosen == "k1k2p1p2", choice.reason
        f = fit.camera.intrinsics
        se = fit.standard_errors
        assert abs(f.u0 - 320.0) < 3.3 * se["u0"] and abs(f.v0 - 240.0) < 3.3 * se["v0"]


def test_too_few_pairs_for_tangential_terms_fit_no_distortion() -> None:
    X = rig(4, n=6)
    uv = camera().project(X) + np.random.default_rng(5).normal(0, 0.3, (6, 2))
    fit, choice = calibrate_choosing_distortion(X, uv)
    assert choice.chosen == "none" and "too few pairs" in choice.reason
    assert np.all(fit.camera.distortion == 0.0)


def test_text_output_says_which_model_and_why(tmp_path, capsys) -> None:
    X = rig(3)
    lens = camera([-0.25, 0.1, 0.001, -0.0005])
    uv = lens.project(X) + np.random.default_rng(7).normal(0, 0.3, (40, 2))
    write_csv(tmp_path / "pairs.csv", X, uv)
    assert main(["calib", "fit", str(tmp_path / "pairs.csv")]) == 0
    text = capsys.readouterr().out
    assert "distortion k1k2p1p2" in text and "F test" in text
    assert "standard errors" in text and "fx " in text


@pytest.mark.parametrize("distortion_terms", [0, 2])
def test_standard_errors_match_the_spread_of_refits(distortion_terms: int) -> None:
    X = rig(11)
    lens = camera([-0.25, 0.1, 0.0, 0.0] if distortion_terms else ())
    rng = np.random.default_rng(9)
    names = ("fx", "fy", "u0", "v0") + (("k1", "k2") if distortion_terms else ())
    truth = {"fx": 800.0, "fy": 800.0, "u0": 320.0, "v0": 240.0, "k1": -0.25, "k2": 0.1}
    runs = 200
    z2 = {name: 0.0 for name in names}
    for _ in range(runs):
        uv = lens.project(X) + rng.normal(0, 0.3, (40, 2))
        fit = calibrate(X, uv, distortion_terms=distortion_terms)
        got = dict(
            zip(("fx", "fy", "skew", "u0", "v0"), fit.camera.intrinsics.as_array(), strict=True)
        )
        got.update(k1=fit.camera.distortion[0], k2=fit.camera.distortion[1])
        for name in names:
            z2[name] += ((got[name] - truth[name]) / fit.standard_errors[name]) ** 2
    low, high = chi2.ppf([0.025, 0.975], runs)
    for name in names:
        assert low < z2[name] < high, (name, z2[name] / runs)
