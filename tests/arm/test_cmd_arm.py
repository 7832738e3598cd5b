"""``umbra arm``: flange pose and Jacobian on the command line."""

from __future__ import annotations

import json

import numpy as np
import pytest

from umbra.modules.arm.dh import puma560
from umbra.modules.arm.jacobian import jacobian, manipulability
from umbra.runtime.cli.main import main

Q = [0.1, 0.7, -3.0, 0.2, 0.6, -0.4]


def test_json_output_matches_the_kinematics(capsys):
    assert main(["arm", "--q", ",".join(map(str, Q)), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert set(result) == {"T_base_flange", "jacobian", "manipulability"}
    table = puma560()
    np.testing.assert_allclose(result["T_base_flange"], table.fk(Q), atol=1e-15)
    J = jacobian(table, Q)
    np.testing.assert_allclose(result["jacobian"], J, atol=1e-15)
    assert result["manipulability"] == pytest.approx(manipulability(J))


def test_degrees_and_text_output(capsys):
    assert main(["arm", "--q-deg", "0,0,0,0,0,0"]) == 0
    text = capsys.readouterr().out
    assert "position 0.45210 -0.15005 1.10363 m" in text  # shoulder 0.67183 m + 0.4318 m
    assert "near a singularity" in text  # q5 = 0
    assert "   vx " in text and "   wz " in text


def test_a_dh_file(tmp_path, capsys):
    path = tmp_path / "two.yaml"
    path.write_text("name: planar\njoints:\n  - {name: a, a: 0.5}\n  - {name: b, a: 0.3}\n")
    assert main(["arm", "--dh", str(path), "--q", "0,1.5707963267948966", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    np.testing.assert_allclose(
        np.array(result["T_base_flange"])[:3, 3], [0.5, 0.3, 0.0], atol=1e-12
    )
    assert np.array(result["jacobian"]).shape == (6, 2)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["arm", "--q", "1,2"], "--q expects 6 finite values"),
        (["arm", "--q", "a,b,c,d,e,f"], "comma-separated numbers"),
    ],
)
def test_bad_joint_values_exit_2(argv, message, capsys):
    assert main(argv) == 2
    assert message in capsys.readouterr().err


def test_bad_dh_file_exits_2_with_file_and_line(tmp_path, capsys):
    path = tmp_path / "bad.yaml"
    path.write_text("joints:\n  - {name: a, alpha_deg: x}\n")
    assert main(["arm", "--dh", str(path), "--q", "0"]) == 2
    assert f"{path}:2: error: joints[0].alpha_deg" in capsys.readouterr().err
