"""Synthetic data with known truth for the camera-pose tool: a camera on a pan-tilt unit whose
mount is off by a few degrees and centimetres, calibration points on a table, clicked pixels.

Frames (metres; z up in the world): ``world`` -> ``ptu_base`` (fixed) -> ``ptu_head`` (pan about
the base's z, then tilt about the head's y; head x looks forward) -> ``camera`` (the mount:
camera z along head x, camera x along head -y, camera y along head -z, i.e. x right, y down).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from umbra.modules.calib.camera_model import Intrinsics, PinholeCamera
from umbra.modules.calib.pose_tool import MountSnapshot
from umbra.modules.calib.synthetic import random_pose
from umbra.modules.geometry.mount_offset import offset_mount
from umbra.modules.geometry.transforms import (
    compose,
    rot_y,
    rot_z,
    transform_from_rotation_translation,
    translation,
)

FloatArray = NDArray[np.float64]

#: camera axes in head axes: columns are camera x, y, z written in the head frame.
R_HEAD_CAMERA = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
#: a 640x480 camera without distortion (the benchmark's clicks are in ideal pixels).
PTU_INTRINSICS = Intrinsics(fx=820.0, fy=815.0, skew=0.0, u0=331.0, v0=244.0)
TILT_AXIS_HEIGHT_M = 0.08


def T_base_head(pan: float, tilt: float) -> FloatArray:
    """Pan-tilt kinematics (radians): ``Rz(pan) . Trans(0, 0, 0.08) . Ry(tilt)``; positive tilt
    turns the head's x (forward) down."""
    return compose(rot_z(pan), translation(0.0, 0.0, TILT_AXIS_HEIGHT_M), rot_y(tilt))


def nominal_T_head_camera() -> FloatArray:
    """The mount as designed: 3 cm forward, 5 cm above the tilt axis, looking along head x."""
    return transform_from_rotation_translation(R_HEAD_CAMERA, [0.03, 0.0, 0.05])


def table_points() -> FloatArray:
    """Eight calibration points at 0.6 to 1.7 m from the PTU (world, metres): tray corners,
    the table's front corners, a box's top corners and two markers on a rack behind the table."""
    return np.array(
        [
            [0.52, -0.30, 0.53],
            [0.70, -0.30, 0.55],
            [0.36, 0.10, 0.32],
            [0.86, 0.10, 0.32],
            [0.42, 0.30, 0.58],
            [0.80, 0.35, 0.60],
            [0.30, 0.75, 0.38],
            [0.90, 0.75, 0.68],
        ]
    )


#: PTU base 0.9 m in front of the table's edge, 0.7 m above the floor, base x along world +y.
T_WORLD_PTU_BASE = compose(translation(0.6, -0.9, 0.7), rot_z(np.pi / 2))


def aim(T_world_base: FloatArray, target: FloatArray) -> tuple[float, float]:
    """Pan and tilt (radians) that point the head's x axis at a world point (nominal mount)."""
    p = np.linalg.solve(T_world_base, np.append(target, 1.0))[:3]
    pan = float(np.arctan2(p[1], p[0]))
    horizontal = float(np.hypot(p[0], p[1]))
    tilt = float(np.arctan2(TILT_AXIS_HEIGHT_M - p[2], horizontal))
    return pan, tilt


@dataclass(frozen=True, eq=False)
class MountCase:
    """One randomized case: the true and nominal mounts and the PTU angles of each snapshot."""

    T_head_camera_true: FloatArray
    T_head_camera_nominal: FloatArray
    pan_tilt: list[tuple[float, float]]
    points: FloatArray


def random_case(
    rng: np.random.Generator,
    snapshots: int = 3,
    points: int = 6,
    max_angle_deg: float = 5.0,
    max_offset_m: float = 0.05,
    spread_deg: float = 6.0,
) -> MountCase:
    """A random mount error up to ``max_angle_deg`` and ``max_offset_m``; ``points`` of the
    calibration points; PTU poses aimed ``spread_deg`` around the points' centroid at equal
    angles (one snapshot: aimed at the centroid)."""
    R, d = random_pose(rng, np.radians(max_angle_deg), max_offset_m / np.sqrt(3.0))
    nominal = nominal_T_head_camera()
    true = offset_mount(nominal, transform_from_rotation_translation(R, d))
    all_points = table_points()
    chosen = all_points[np.sort(rng.choice(len(all_points), size=points, replace=False))]
    pan0, tilt0 = aim(T_WORLD_PTU_BASE, all_points.mean(axis=0))
    spread = np.radians(spread_deg) if snapshots > 1 else 0.0
    pan_tilt = [
        (pan0 + spread * np.cos(a), tilt0 + spread * np.sin(a))
        for a in np.pi / 2 + 2 * np.pi * np.arange(snapshots) / snapshots
    ]
    return MountCase(true, nominal, pan_tilt, chosen)


def click_snapshots(
    case: MountCase, noise_px: float, rng: np.random.Generator, image_size=(640, 480)
) -> list[MountSnapshot]:
    """Snapshots of the case's points seen through the true mount, clicks with Gaussian noise
    of ``noise_px`` per axis; points outside the image or behind the camera are not clicked."""
    camera = PinholeCamera(PTU_INTRINSICS)
    out = []
    for pan, tilt in case.pan_tilt:
        T_world_head = T_WORLD_PTU_BASE @ T_base_head(pan, tilt)
        seen = camera.with_extrinsic_matrix(np.linalg.inv(T_world_head @ case.T_head_camera_true))
        depth = seen.to_camera_frame(case.points)[:, 2]
        pixels = seen.project(case.points)
        inside = (
            (depth > 0)
            & (pixels[:, 0] >= 0)
            & (pixels[:, 0] < image_size[0])
            & (pixels[:, 1] >= 0)
            & (pixels[:, 1] < image_size[1])
        )
        clicks = pixels[inside] + rng.normal(0.0, noise_px, (int(inside.sum()), 2))
        out.append(MountSnapshot(camera, case.points[inside], clicks, T_world_head))
    return out
