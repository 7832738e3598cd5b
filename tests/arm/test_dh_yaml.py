"""Loading DH tables from YAML files and dicts, with errors that point at the problem."""

from __future__ import annotations

import numpy as np
import pytest

from umbra.modules.arm.dh import DHError, puma560
from umbra.modules.arm.dh_yaml import dh_table_from_dict, load_dh_table

PUMA_YAML = """\
name: puma560
joints:
  - {name: j1, d: 0.67183, a: 0, alpha_deg: 90, limits_deg: [-160, 160], max_rate: 1.4}
  - {name: j2, d: 0, a: 0.4318, alpha_deg: 0, limits_deg: [-45, 225], max_rate: 1.3}
  - {name: j3, d: 0.15005, a: 0.0203, alpha_deg: -90, limits_deg: [-225, 45], max_rate: 2.1}
  - {name: j4, d: 0.4318, a: 0, alpha_deg: 90, limits_deg: [-110, 170], max_rate: 4.0}
  - {name: j5, d: 0, a: 0, alpha_deg: -90, limits_deg: [-100, 100], max_rate: 4.2}
  - {name: j6, d: 0, a: 0, alpha_deg: 0, limits_deg: [-266, 266], max_rate: 4.0}
"""


def test_yaml_puma_matches_the_built_in_table(tmp_path):
    path = tmp_path / "puma.yaml"
    path.write_text(PUMA_YAML)
    table = load_dh_table(path)
    builtin = puma560()
    assert table.names == builtin.names
    np.testing.assert_allclose(table.q_min, builtin.q_min)
    np.testing.assert_allclose(table.qd_max, builtin.qd_max)
    q = np.radians([10, 20, -30, 40, 50, 60])
    np.testing.assert_allclose(table.fk(q), builtin.fk(q), atol=1e-12)


def test_dict_with_radians_and_a_prismatic_joint():
    table = dh_table_from_dict(
        {
            "joints": [
                {"name": "turn", "alpha": 1.5707963267948966, "theta_deg": 10},
                {"name": "lift", "type": "prismatic", "limits": [0.0, 0.3], "max_rate": 0.1},
            ]
        }
    )
    assert table.name == "arm"
    assert not table.revolute[1]
    assert table.joints[0].theta == pytest.approx(np.radians(10))
    assert table.fk([0.0, 0.2])[2, 3] == pytest.approx(0.0)  # lifts along z0 rotated by alpha


@pytest.mark.parametrize(
    ("text", "line", "fragment"),
    [
        (
            "joints:\n  - {name: j1, alpha_deg: ninety}\n",
            2,
            "joints[0].alpha_deg: expected a number",
        ),
        ("joints:\n  - name: j1\n    lenght: 0.3\n", 3, "unknown key 'lenght'"),
        ("joints:\n  - {name: j1}\n  - {name: j1}\n", 3, "already used by joints[0]"),
        ("joints:\n  - {name: j1, limits_deg: [10, -10]}\n", 2, "expected min < max"),
        ("joints:\n  - {name: j1, type: ball}\n", 2, "expected revolute or prismatic"),
        ("joints:\n  - {name: j1, alpha: 1, alpha_deg: 2}\n", 2, "not both"),
        ("name: x\n", 1, "joints: expected a non-empty list"),
        (
            "joints:\n  - {name: s, type: prismatic, limits_deg: [0, 1]}\n",
            2,
            "prismatic joint takes limits in metres",
        ),
        ("joints: [\n", 2, "invalid YAML"),
    ],
)
def test_file_errors_name_file_line_and_key(tmp_path, text, line, fragment):
    path = tmp_path / "arm.yaml"
    path.write_text(text)
    with pytest.raises(DHError) as info:
        load_dh_table(path)
    message = str(info.value)
    assert message.startswith(f"{path}:{line}: error: "), message
    assert fragment in message


def test_missing_file_is_a_clear_error(tmp_path):
    with pytest.raises(DHError, match="cannot read DH file"):
        load_dh_table(tmp_path / "nope.yaml")


def test_dict_errors_name_the_key_path():
    with pytest.raises(DHError, match=r"^joints\[1\]\.max_rate: expected a positive rate"):
        dh_table_from_dict({"joints": [{"name": "a"}, {"name": "b", "max_rate": -1}]})
    with pytest.raises(DHError, match="expected a mapping"):
        dh_table_from_dict([1, 2])  # type: ignore[arg-type]
