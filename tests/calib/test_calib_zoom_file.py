"""The Appendix D zoom calibration file: the report's own file, round trips, malformed files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from umbra.connectors.errors import UserError
from umbra.modules.calib.zoom_io import load_zoom_file, load_zoom_table, save_zoom_file
from umbra.modules.calib.zoom_xml import format_zoom_xml, parse_zoom_xml
from umbra.modules.calib.zoom_yaml import parse_zoom_yaml

REPO = Path(__file__).resolve().parents[2]
REPORT_FILE = REPO / "modules" / "calib" / "data" / "zoom_cam.xml"
SHARED_FILE = Path("/work/shared/data/zoom_cam.xml")


def test_shipped_copy_is_the_report_file() -> None:
    if not SHARED_FILE.exists():
        pytest.skip(f"no shared copy of the report's file at {SHARED_FILE}")
    assert REPORT_FILE.read_bytes() == SHARED_FILE.read_bytes()


def test_report_file_loads_as_printed() -> None:
    zoom_file = load_zoom_file(REPORT_FILE)
    table = zoom_file.camera()
    assert table.name == "zcam"
    assert zoom_file.recorded_path == "C:/ieddApps/camera/zoom_cam.xml"
    assert "Sony FCB" in zoom_file.comment
    np.testing.assert_array_equal(table.zooms, [0.0, 0.025, 0.05, 0.1, 0.15, 0.3, 0.4, 1.0])
    np.testing.assert_array_equal(
        table.intrinsics[0], [740.09, 741.60, -4.58, 344.25, 212.84, 0, 0, 0, 0]
    )
    np.testing.assert_array_equal(table.extrinsics[2], [-0.002, 0.041, -0.0, 0.022, 0.022, 0.032])
    np.testing.assert_array_equal(table.intrinsics[-1, :2], [29600.0, 29600.0])
    assert table.intrinsics.shape == (8, 9) and table.extrinsics.shape == (8, 6)


def test_interpolation_on_report_table() -> None:
    table = load_zoom_table(REPORT_FILE)
    for i, zoom in enumerate(table.zooms):  # exact at tabulated zooms
        sample = table.sample(zoom)
        np.testing.assert_allclose(sample.intrinsics, table.intrinsics[i], rtol=1e-12)
        np.testing.assert_allclose(sample.extrinsics, table.extrinsics[i], atol=1e-15)
    # Linear, as the report: halfway between 0.1 and 0.15.
    linear = table.sample(0.125)
    assert linear.intrinsics[0] == pytest.approx((1004.12 + 1208.51) / 2)
    assert linear.extrinsics[2] == pytest.approx((0.008 + 0.014) / 2)
    fx = [table.sample(z).intrinsics[0] for z in np.linspace(0, 1, 401)]
    assert np.all(np.diff(fx) > 0)


def test_camera_model_at_zoom() -> None:
    table = load_zoom_table(REPORT_FILE)
    camera = table.sample(0.0).camera()
    assert camera.intrinsics.fx == 740.09 and camera.intrinsics.skew == -4.58
    np.testing.assert_allclose(camera.d, [-0.004, 0.041, 0.006])
    assert np.linalg.det(camera.R) == pytest.approx(1.0)
    # Small angles: R ~ I + [theta]_x.
    np.testing.assert_allclose(camera.R[2, 1], 0.009, atol=1e-3)
    as_dict = table.sample(0.2).as_dict()
    assert set(as_dict["intrinsics"]) == {"fx", "fy", "skew", "u0", "v0", "k1", "k2", "p1", "p2"}
    assert set(as_dict["extrinsics"]) == {"dx", "dy", "dz", "rx", "ry", "rz"}


def test_zoom_outside_range() -> None:
    table = load_zoom_table(REPORT_FILE)
    with pytest.raises(ValueError, match=r"0\.\.1"):
        table.sample(1.5)
    short = parse_zoom_xml(format_zoom_xml(load_zoom_file(REPORT_FILE))).camera()
    assert short.sample(1.0).intrinsics[0] == 29600.0


def test_xml_and_yaml_round_trip_exactly(tmp_path: Path) -> None:
    original = load_zoom_file(REPORT_FILE)
    for name in ("again.xml", "again.yaml", "again.yml"):
        save_zoom_file(tmp_path / name, original)
        back = load_zoom_file(tmp_path / name)
        assert back.comment == original.comment
        assert back.recorded_path == original.recorded_path
        np.testing.assert_array_equal(back.camera().zooms, original.camera().zooms)
        np.testing.assert_array_equal(back.camera().intrinsics, original.camera().intrinsics)
        np.testing.assert_array_equal(back.camera().extrinsics, original.camera().extrinsics)


def test_shipped_yaml_matches_xml() -> None:
    xml = load_zoom_table(REPORT_FILE)
    yml = load_zoom_table(REPO / "modules" / "calib" / "data" / "zoom_cam.yaml")
    np.testing.assert_array_equal(xml.intrinsics, yml.intrinsics)
    np.testing.assert_array_equal(xml.extrinsics, yml.extrinsics)


def test_yaml_units_are_converted() -> None:
    text = """\
units: {length: mm, angle: deg}
cameras:
  - name: c
    zooms:
      - zoom: 0.5
        intrinsics: {fx: 1, fy: 1, skew: 0, u0: 0, v0: 0, k1: 0, k2: 0, p1: 0, p2: 0}
        extrinsics: {dx: 41, dy: 0, dz: 0, rx: 90, ry: 0, rz: 0}
"""
    table = parse_zoom_yaml(text).camera()
    assert table.extrinsics[0, 0] == pytest.approx(0.041)
    assert table.extrinsics[0, 3] == pytest.approx(np.pi / 2)


def test_several_cameras_are_selected_by_name(tmp_path: Path) -> None:
    text = REPORT_FILE.read_text()
    camera = text[text.index("<SR_cam>") : text.index("</SR_cam>") + len("</SR_cam>")]
    doubled = text.replace("</SR_world>", camera.replace("zcam", "left") + "\n</SR_world>")
    path = tmp_path / "two.xml"
    path.write_text(doubled)
    assert load_zoom_table(path, "left").name == "left"
    with pytest.raises(UserError, match="several cameras"):
        load_zoom_table(path)
    with pytest.raises(UserError, match="no camera 'right'"):
        load_zoom_table(path, "right")


GOOD_ZOOM = """  <SR_zoom> 0.5
    <SR_cam_int> {800 800 0 320 240 0 0 0 0} </SR_cam_int>
    <SR_cam_ext> {0 0 0 0 0 0} </SR_cam_ext>
  </SR_zoom>"""


def document(*zoom_blocks: str, root: str = "SR_world") -> str:
    return (
        "\n".join(
            [
                '<?xml version="1.0"?>',
                f"<{root}>",
                "<SR_cam> zcam",
                *zoom_blocks,
                "</SR_cam>",
                f"</{root}>",
            ]
        )
        + "\n"
    )


def edited(old: str, new: str) -> str:
    """A one-camera document whose single zoom entry has ``old`` replaced by ``new``."""
    return document(GOOD_ZOOM.replace(old, new))


MALFORMED_XML = {
    # name: (text, line, message fragment)
    "not_xml": ("fx: 800\nfy: 800\n", 1, "not well-formed XML"),
    "empty": ("", 1, "not well-formed XML: no element found"),
    "unclosed_tag": (
        document(GOOD_ZOOM).replace("</SR_cam_ext>\n  </SR_zoom>", "</SR_cam_ext>\n"),
        8,
        "not well-formed XML: mismatched tag",
    ),
    "wrong_root": (document(GOOD_ZOOM, root="SR_universe"), 2, "expected <SR_world>"),
    "missing_value": (
        edited("320 240 0 0 0 0}", "320 240 0 0 0}"),
        5,
        "needs 9 values {fx fy fxy u0 v0 k1 k2 p1 p2}, found 8",
    ),
    "missing_extrinsic_value": (
        edited("{0 0 0 0 0 0}", "{0 0 0 0 0}"),
        6,
        "needs 6 values {dx dy dz thetax thetay thetaz}, found 5",
    ),
    "bad_number": (
        edited("{800 800", "{800 8OO"),
        5,
        "bad number '8OO'",
    ),
    "nan_number": (edited("{0 0 0 0 0 0}", "{0 0 nan 0 0 0}"), 6, "finite"),
    "no_braces": (
        edited("{0 0 0 0 0 0}", "0 0 0 0 0 0"),
        6,
        "enclosed in braces",
    ),
    "zoom_above_one": (
        document(GOOD_ZOOM, GOOD_ZOOM.replace("0.5", "1.25")),
        8,
        "zoom 1.25 is outside the normalized range 0..1",
    ),
    "zoom_negative": (edited("0.5", "-0.1"), 4, "outside the normalized"),
    "non_monotonic": (
        document(GOOD_ZOOM, GOOD_ZOOM.replace("0.5", "0.7"), GOOD_ZOOM.replace("0.5", "0.6")),
        12,
        "zoom 0.6 does not increase from the previous zoom 0.7 (line 8)",
    ),
    "repeated_zoom": (document(GOOD_ZOOM, GOOD_ZOOM), 8, "does not increase"),
    "zoom_not_a_number": (edited("0.5", "half"), 4, "bad number 'half'"),
    "zoom_missing": (edited(" 0.5", ""), 4, "needs a normalized zoom"),
    "missing_intrinsics": (
        edited("    <SR_cam_int> {800 800 0 320 240 0 0 0 0} </SR_cam_int>\n", ""),
        4,
        "has no <SR_cam_int>",
    ),
    "duplicate_extrinsics": (
        edited("  </SR_zoom>", "    <SR_cam_ext> {0 0 0 0 0 0} </SR_cam_ext>\n  </SR_zoom>"),
        7,
        "second <SR_cam_ext>",
    ),
    "unknown_element": (
        edited("SR_cam_ext>", "SR_cam_extr>"),
        6,
        "unexpected element",
    ),
    "negative_focal": (
        edited("{800 800", "{-800 800"),
        5,
        "focal lengths must be positive",
    ),
    "text_after_children": (
        edited("  </SR_zoom>", "  0.6\n  </SR_zoom>"),
        7,
        "unexpected text",
    ),
    "camera_without_zooms": (document(), 3, "has no <SR_zoom>"),
    "doctype": (
        '<?xml version="1.0"?>\n<!DOCTYPE x [<!ENTITY a "b">]>\n' + document(GOOD_ZOOM)[22:],
        2,
        "DOCTYPE",
    ),
}


def assert_load_error(path: Path, text: str, line: int, fragment: str) -> None:
    """Loading ``text`` from ``path`` fails with ``PATH:LINE: error: ...fragment...``."""
    path.write_text(text)
    with pytest.raises(UserError) as caught:
        load_zoom_file(path)
    message = str(caught.value)
    assert message.startswith(f"{path}:{line}: error: "), message
    assert fragment in message, message
    assert "Traceback" not in message


@pytest.mark.parametrize("name", sorted(MALFORMED_XML))
def test_malformed_xml_reports_file_and_line(tmp_path: Path, name: str) -> None:
    assert_load_error(tmp_path / f"{name}.xml", *MALFORMED_XML[name])


GOOD_YAML = """\
cameras:
  - name: zcam
    zooms:
      - zoom: 0.1
        intrinsics: {fx: 800, fy: 800, skew: 0, u0: 320, v0: 240, k1: 0, k2: 0, p1: 0, p2: 0}
        extrinsics: {dx: 0, dy: 0.04, dz: 0, rx: 0, ry: 0, rz: 0}
      - zoom: 0.2
        intrinsics: {fx: 900, fy: 900, skew: 0, u0: 320, v0: 240, k1: 0, k2: 0, p1: 0, p2: 0}
        extrinsics: {dx: 0, dy: 0.04, dz: 0, rx: 0, ry: 0, rz: 0}
"""

MALFORMED_YAML = {
    "syntax": ("cameras: [\n  - name: x\n", 2, "invalid YAML"),
    "missing_fx": (GOOD_YAML.replace("{fx: 900, ", "{"), 8, "missing 'fx'"),
    "bad_number": (
        GOOD_YAML.replace(
            "dy: 0.04, dz: 0, rx: 0, ry: 0, rz: 0}\n      - zoom: 0.2",
            "dy: 0.04, dz: zero, rx: 0, ry: 0, rz: 0}\n      - zoom: 0.2",
        ),
        6,
        "bad number 'zero'",
    ),
    "non_monotonic": (
        GOOD_YAML.replace("zoom: 0.2", "zoom: 0.05"),
        7,
        "does not increase from the previous zoom 0.1 (line 4)",
    ),
    "zoom_range": (GOOD_YAML.replace("zoom: 0.2", "zoom: 2"), 7, "outside the normalized range"),
    "unknown_key": (GOOD_YAML.replace("    zooms:", "    zoomz:"), 3, "unknown key 'zoomz'"),
    "bad_unit": ("units: {length: inch}\n" + GOOD_YAML, 1, "units.length must be one of"),
    "empty": ("", 1, "empty"),
}


@pytest.mark.parametrize("name", sorted(MALFORMED_YAML))
def test_malformed_yaml_reports_file_and_line(tmp_path: Path, name: str) -> None:
    assert_load_error(tmp_path / f"{name}.yaml", *MALFORMED_YAML[name])


def test_good_yaml_loads() -> None:
    table = parse_zoom_yaml(GOOD_YAML).camera()
    assert table.sample(0.15).intrinsics[0] == pytest.approx(850.0)


def test_missing_file_and_unknown_extension(tmp_path: Path) -> None:
    with pytest.raises(UserError, match="cannot read"):
        load_zoom_file(tmp_path / "nowhere.xml")
    with pytest.raises(UserError, match="unknown calibration file type"):
        load_zoom_file(tmp_path / "cal.txt")
