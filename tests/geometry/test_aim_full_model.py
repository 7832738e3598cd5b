"""Issue #31 item 1: aiming a zoom camera uses its whole model at the current zoom.

The reference is built here from the report's Appendix D file (read with the standard library's
XML parser, interpolated linearly with ``numpy.interp``), the head's chain written out with
scipy's rotations, and the projection with OpenCV (``cv2.projectPoints``; the skew added on the
distorted normalized coordinates, which OpenCV has no term for). A target is centred when it
shows within 2 px of the principal point (where the optic axis meets the image).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from umbra.connectors.ptu_messages import PtuCommand
from umbra.modules.calib.camcalib import REPORT_FILE
from umbra.modules.calib.camera_model import Intrinsics, PinholeCamera
from umbra.modules.geometry.rochester_head import (
    ROCHESTER_HEAD,
    aim_camera_at_point,
    aim_camera_model_at_point,
)
from umbra.modules.ptu.ptu_module import Ptu
from umbra.modules.sketch.rig import default_rig
from umbra.runtime.harness import ModuleHarness

ZOOMS = np.linspace(0.0, 1.0, 41)
#: points the Active Sketch rig watches (m, base): the arm's workspace in front of the mast
TARGETS = ([0.6, 0.0, 0.3], [0.45, -0.2, 0.1], [0.9, 0.3, 0.5])


def _zoom_row(zoom: float) -> tuple[np.ndarray, np.ndarray]:
    root = ET.parse(REPORT_FILE).getroot()
    z, intr, extr = [], [], []
    for entry in root.iter("SR_zoom"):
        z.append(float(entry.text.split()[0]))
        intr.append([float(v) for v in entry.find("SR_cam_int").text.strip(" {}\n").split()])
        extr.append([float(v) for v in entry.find("SR_cam_ext").text.strip(" {}\n").split()])
    i = np.array([np.interp(zoom, z, c) for c in np.array(intr).T])
    e = np.array([np.interp(zoom, z, c) for c in np.array(extr).T])
    return i, e


def _pixel(T_base_mount: np.ndarray, zoom: float, point: np.ndarray) -> tuple[np.ndarray, tuple]:
    """Pixel of ``point`` and the principal point, camera in the mount per the zoom file."""
    i, e = _zoom_row(zoom)
    R = Rotation.from_euler("xyz", e[3:]).as_matrix()  # Rz(rz) Ry(ry) Rx(rx): X_cam = R X + d
    T_mount_base = np.linalg.inv(T_base_mount)
    X_mount = T_mount_base[:3, :3] @ point + T_mount_base[:3, 3]
    X_cam = R @ X_mount + e[:3]
    assert X_cam[2] > 0
    K0 = np.array([[i[0], 0.0, i[3]], [0.0, i[1], i[4]], [0.0, 0.0, 1.0]])
    uv, _ = cv2.projectPoints(X_cam.reshape(1, 1, 3), np.zeros(3), np.zeros(3), K0, i[5:9])
    u, v = uv.reshape(2)
    u += i[2] * (v - i[4]) / i[1]  # skew: fxy times the distorted normalized y
    return np.array([u, v]), (i[3], i[4])


def _rochester_chain(phi: float, theta: float, head=ROCHESTER_HEAD, eye: float = 0.0) -> np.ndarray:
    """The guide's A9..A14 with scipy's rotations (CamPos in FLANGE)."""

    def trans(x, y, z):
        T = np.eye(4)
        T[:3, 3] = (x, y, z)
        return T

    def rot(axis, angle):
        T = np.eye(4)
        T[:3, :3] = Rotation.from_rotvec(np.array(axis, float) * angle).as_matrix()
        return T

    return (
        trans(0, head.neck_offset, 0)
        @ trans(eye, 0, 0)
        @ rot((1, 0, 0), phi)
        @ trans(0, head.alt_offset, 0)
        @ rot((0, 1, 0), theta)
        @ trans(0, 0, head.az_offset)
    )


def _ptu_mount(T_base_ptu, pan, tilt):
    return T_base_ptu @ _rochester_chain(tilt, pan, _ptu_head())


def _ptu_head():
    from umbra.modules.ptu.ptu_model import PtuGeometry

    return PtuGeometry().head


@pytest.mark.parametrize("target", TARGETS)
def test_sketch_rig_centres_the_target_at_every_zoom(target) -> None:
    point = np.asarray(target, dtype=float)
    for camera in default_rig():
        worst = 0.0
        for zoom in ZOOMS:
            pan, tilt = camera.aim(point, zoom)
            uv, centre = _pixel(_ptu_mount(camera.T_base_ptu, pan, tilt), zoom, point)
            worst = max(worst, float(np.hypot(*(uv - centre))))
        assert worst < 2.0, (camera.name, worst)


def test_ptu_module_keeps_a_watched_point_centred_as_the_zoom_changes() -> None:
    rig = default_rig()[0]
    point = np.array([0.6, 0.1, 0.3])
    frames = {"base->ptu_left": rig.T_base_ptu}
    params = {"ptu_frame": "ptu_left", "mount_name": "mount_left"}
    with ModuleHarness(Ptu, params, frames=frames) as h:
        h.push("camera", rig.model(0.0))
        h.push("command", PtuCommand(mode="point", point=point))
        for zoom in (0.0, 0.35, 0.6, 1.0):
            if zoom:
                h.push("camera", rig.model(zoom))  # the operator zooms in: a new model
            for _ in range(200):
                h.step(dt=0.01)
            state = h.output("state")
            assert not state.moving and state.status == "ok"
            uv, centre = _pixel(h.output("mount_pose").matrix, zoom, point)
            assert np.hypot(*(uv - centre)) < 2.0, (zoom, uv, centre)


def test_rochester_head_aims_a_camera_rotated_in_campos() -> None:
    # a camera 2 deg off CamPos's axis, offset 1 cm, 12000 px focal length, distorted
    rvec = np.array([0.02, -0.03, 0.01])
    R = Rotation.from_rotvec(rvec).as_matrix()
    d = np.array([0.01, -0.004, 0.003])
    dist = np.array([-0.2, 0.05, 0.001, 0.0005, 0.0])
    camera = PinholeCamera(Intrinsics(12000.0, 12050.0, -3.0, 330.0, 230.0), R, d, dist)

    def project(point_campos):
        return camera.project(point_campos)

    point = np.array([0.2, -0.1, 1.8])
    phi, theta = aim_camera_model_at_point(point, "right", project, (330.0, 230.0))
    T = _rochester_chain(phi, theta, eye=ROCHESTER_HEAD.right_offset)
    X = np.linalg.solve(T, np.append(point, 1.0))[:3]
    K0 = np.array([[12000.0, 0, 330.0], [0, 12050.0, 230.0], [0, 0, 1]])
    uv, _ = cv2.projectPoints(X.reshape(1, 1, 3), cv2.Rodrigues(R)[0], d, K0, dist)
    u, v = uv.reshape(2)
    u += -3.0 * (v - 230.0) / 12050.0
    assert np.hypot(u - 330.0, v - 230.0) < 2.0
    # the guide's closed form alone misses by hundreds of pixels with this camera
    phi0, theta0 = aim_camera_at_point(point, "right")
    X0 = np.linalg.solve(
        _rochester_chain(phi0, theta0, eye=ROCHESTER_HEAD.right_offset), np.append(point, 1.0)
    )[:3]
    uv0, _ = cv2.projectPoints(X0.reshape(1, 1, 3), cv2.Rodrigues(R)[0], d, K0, dist)
    assert np.hypot(*(uv0.reshape(2) - (330.0, 230.0))) > 100.0
