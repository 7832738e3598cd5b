"""Issue #31 item 2: one zoom interpolation (the report's linear rule) for every consumer.

The reference reads the report's Appendix D file with the standard library's XML parser and
interpolates each column with ``numpy.interp``; CamCalib, ``umbra calib zoom``, the cameras file
of ``umbra calib pose`` and the Active Sketch rig must all give its values.
"""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from umbra.connectors.messages import ZoomState
from umbra.modules.calib.camcalib import REPORT_FILE, CamCalib
from umbra.modules.calib.camera_file import load_cameras
from umbra.modules.sketch.rig import default_rig
from umbra.runtime.cli.main import main
from umbra.runtime.harness import ModuleHarness

ZOOMS = (0.01, 0.0375, 0.07, 0.125, 0.2, 0.35, 0.5, 0.77, 0.95)


def _reference_table() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    root = ET.parse(REPORT_FILE).getroot()
    zooms, intr, extr = [], [], []
    for entry in root.iter("SR_zoom"):
        zooms.append(float(entry.text.split()[0]))
        intr.append([float(v) for v in entry.find("SR_cam_int").text.strip(" {}\n").split()])
        extr.append([float(v) for v in entry.find("SR_cam_ext").text.strip(" {}\n").split()])
    return np.array(zooms), np.array(intr), np.array(extr)


def _reference(zoom: float) -> tuple[np.ndarray, np.ndarray]:
    z, intr, extr = _reference_table()
    return (
        np.array([np.interp(zoom, z, c) for c in intr.T]),
        np.array([np.interp(zoom, z, c) for c in extr.T]),
    )


def test_report_rule_gives_7850_px_at_zoom_half() -> None:
    # 3500 px at 0.4, 29600 px at 1.0: a sixth of the way is 3500 + 26100 / 6 = 7850 px.
    assert _reference(0.5)[0][0] == pytest.approx(7850.0)


@pytest.mark.parametrize("zoom", ZOOMS)
def test_camcalib_uses_the_report_rule(zoom: float) -> None:
    intr, _ = _reference(zoom)
    with ModuleHarness(CamCalib, {}) as h:
        h.push("zoom", ZoomState(zoom=zoom))
        model = h.step(0.1)["camera"][0]
    got = [model.fx, model.fy, model.skew, model.u0, model.v0]
    np.testing.assert_allclose(got, intr[:5], rtol=1e-12)


@pytest.mark.parametrize("zoom", ZOOMS)
def test_calib_zoom_cli_uses_the_report_rule(zoom: float, capsys) -> None:
    assert main(["calib", "zoom", str(REPORT_FILE), "--at", str(zoom), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    intr, extr = _reference(zoom)
    np.testing.assert_allclose(list(data["intrinsics"].values()), intr, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(list(data["extrinsics"].values()), extr, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("zoom", ZOOMS)
def test_sketch_rig_and_cameras_file_use_the_report_rule(zoom: float, tmp_path) -> None:
    intr, _ = _reference(zoom)
    model = default_rig()[0].model(zoom)
    np.testing.assert_allclose([model.fx, model.fy, model.skew], intr[:3], rtol=1e-12)
    path = tmp_path / "cameras.yaml"
    path.write_text(
        "cameras:\n  zc:\n"
        f"    zoom_file: {REPORT_FILE}\n    zoom: {zoom}\n"
        "    mount_pose: {xyz: [0, 0, 0]}\n"
    )
    camera = load_cameras(path)["zc"]
    np.testing.assert_allclose(camera.intrinsics.as_array(), intr[:5], rtol=1e-12)


def test_cameras_file_refuses_another_interpolation(tmp_path) -> None:
    path = tmp_path / "cameras.yaml"
    path.write_text(
        "cameras:\n  zc:\n"
        f"    zoom_file: {REPORT_FILE}\n    zoom: 0.2\n    method: pchip\n"
        "    mount_pose: {xyz: [0, 0, 0]}\n"
    )
    with pytest.raises(Exception) as caught:
        load_cameras(path)
    message = str(caught.value)
    assert "cameras.yaml:5" in message and "linear" in message and "'pchip'" in message
