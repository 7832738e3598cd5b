"""nPnP and ``umbra pose-tool`` on degenerate and noise-free input: a pose or a one-line reason
(exit 2), never a ``LinAlgError`` or ``ZeroDivisionError`` traceback."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.stats import chi2

from umbra.modules.calib.camera_model import Intrinsics, PinholeCamera
from umbra.modules.calib.npnp import View, solve_npnp
from umbra.modules.calib.npnp_warnings import MIN_PIXEL_SIGMA, pose_warnings
from umbra.modules.calib.rotations import rotation_from_vector, vector_from_rotation
from umbra.runtime.cli.main import main

CAMERA = PinholeCamera(Intrinsics(800.0, 800.0, 0.0, 320.0, 240.0), np.eye(3), np.zeros(3))
#: Points (camera frame = input frame, metres) whose pixels are exact binary fractions: the
#: noise-free solution reprojects them with a residual of 0 to rounding.
POINTS = np.array(
    [[0, 0, 1], [0.25, 0, 1], [0, 0.25, 1], [0.25, 0.25, 2], [-0.25, 0.5, 2], [0.5, -0.25, 4]]
)


@pytest.mark.parametrize("pixel_sigma", [None, 0.0])
def test_noise_free_clicks_give_the_pose_with_a_zero_residual(pixel_sigma: float | None) -> None:
    pixels = CAMERA.project(POINTS)
    assert pixels.tolist()[:3] == [[320.0, 240.0], [520.0, 240.0], [320.0, 440.0]]
    result = solve_npnp([View(CAMERA, POINTS, pixels)], pixel_sigma=pixel_sigma)
    # zero to rounding: the noise estimated from it is floored at MIN_PIXEL_SIGMA
    assert result.rms_px < 1e-9
    assert np.linalg.norm(vector_from_rotation(result.R)) < 1e-9
    assert np.linalg.norm(result.d) < 1e-9
    assert result.warnings == ()


def test_the_rival_minimum_test_is_finite_at_a_zero_residual() -> None:
    """At a zero best residual the noise is floored at MIN_PIXEL_SIGMA (0.01 px): a rival pose
    30 deg away that fits to 0.001 px is reported as equally good; one at 0.5 px is not."""
    best = ("SQPnP on view 0", np.eye(3), np.zeros(3), np.zeros(12), 3)
    R_far = rotation_from_vector([0.0, 0.0, np.radians(30.0)])
    close = ("EPnP on view 0", R_far, np.zeros(3), np.full(12, 0.001), 5)
    assert chi2.ppf(0.95, 6) > 12 * 0.001**2 / MIN_PIXEL_SIGMA**2  # 0.12 < 12.6
    (warning,) = pose_warnings([best, close], {}, False, None)
    assert warning.startswith("degenerate geometry: another pose 30.0 deg away (EPnP on view 0)")
    apart = ("EPnP on view 0", R_far, np.zeros(3), np.full(12, 0.5), 5)
    assert pose_warnings([best, apart], {}, False, None) == ()
    assert pose_warnings([best, apart], {}, False, 0.0) == ()


SESSION = """mount: ptu_head->camera
{initial}camera: {{fx: {fx}, fy: 800, u0: 320, v0: 240}}
points:
  a: [0.0, 0.0, 0.5]
  b: [0.1, 0.0, 0.5]
  c: [0.0, 0.1, 0.5]
  d: [0.1, 0.1, 0.6]
snapshots:
  - clicks: {clicks}
"""
GOOD_CLICKS = "{a: [320, 240], b: [480, 240], c: [320, 400], d: [453.333, 373.333]}"


def pose_tool(tmp_path: Path, capsys, *args: str, **fields: str) -> tuple[int, str, str]:
    values = {"initial": "", "fx": "800", "clicks": GOOD_CLICKS, **fields}
    path = tmp_path / "session.yaml"
    path.write_text(SESSION.format(**values))
    code = main(["pose-tool", str(path), *args])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_a_believed_mount_with_the_points_at_the_camera_centre_is_a_bad_start(
    tmp_path: Path, capsys
) -> None:
    """The believed mount puts three clicked points in the camera's own plane (depth 0): that
    start cannot be linearized, the others solve it, and the tool says so."""
    initial = "initial: {xyz: [0, 0, 0.5]}\n"
    code, out, err = pose_tool(tmp_path, capsys, initial=initial)
    assert code == 0, err
    assert err == ""  # no traceback, no numpy warning
    assert "reprojection RMS 0.000 px" in out
    assert "warning: bad start: from the given initial pose the solver failed" in out
    assert "a point at a camera's centre" in out


@pytest.mark.parametrize(
    ("fields", "reason"),
    [
        (
            {"clicks": "{a: [320, 240], b: [320, 240], c: [320, 240], d: [320, 240]}"},
            "do not determine all six pose parameters",
        ),
        ({"fx": "1e-300"}, "the reprojection is not finite"),
    ],
    ids=["four-points-clicked-on-one-pixel", "focal-length-1e-300"],
)
def test_degenerate_sessions_are_refused_in_one_line(
    tmp_path: Path, capsys, fields: dict[str, str], reason: str
) -> None:
    code, out, err = pose_tool(tmp_path, capsys, **fields)
    assert code == 2 and out == ""
    assert err.count("\n") == 1, err
    assert err.startswith(f"{tmp_path / 'session.yaml'}: error: cannot solve the mount: ")
    assert reason in err
