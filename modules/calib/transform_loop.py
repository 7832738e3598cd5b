"""Section 5.4 of the Sandia report: the calibration transform loop, and pose from it.

A point ``x`` of a target object reaches the image through five transforms (equation 31):

    pixel ~ C_int . T_ext . T_kin^-1 . T_dev^-1 . T_obj . x

with the report's names, written here as poses ("pose of frame b in frame a" maps b-coordinates
to a-coordinates):

* ``T_obj = T_world_obj``: the target object in the world (unknown, or known);
* ``T_dev = T_world_dev``: the imaging device's base (robot, PTU base) in the world;
* ``T_kin = T_dev_mount``: the device kinematics at the snapshot's joint angles, the camera mount
  (PTU head, robot flange) in the device base; known, changes from snapshot to snapshot;
* ``T_ext = T_cam_mount``: the camera extrinsics (``camera.R``, ``camera.d``), mount points into
  the camera frame; from the bench calibration (the zoom file's extrinsics);
* ``C_int``: intrinsics and distortion (``camera.intrinsics``, ``camera.distortion``).

Pose estimation solves for ``T_obj`` (everything else known) or for ``T_dev`` (the object known)
from any mix of snapshots: one image with many points, many images with one point each, or both.
Every transform here is a 4x4 homogeneous matrix in metres.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from umbra.modules.calib.camera_model import PinholeCamera
from umbra.modules.calib.npnp import PoseResult, View, solve_npnp
from umbra.modules.calib.rotations import invert_transform
from umbra.modules.geometry.transforms import transform_points

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class Snapshot:
    """One image: the camera (intrinsics, distortion, ``T_cam_mount`` extrinsics), the device
    kinematics ``T_dev_mount`` when it was taken, object points (metres, object frame) and their
    measured pixels."""

    camera: PinholeCamera
    T_dev_mount: FloatArray
    points_obj: FloatArray
    pixels: FloatArray


def camera_from_world(snapshot: Snapshot, T_world_dev: ArrayLike) -> FloatArray:
    """``T_cam_world = T_ext . T_kin^-1 . T_dev^-1`` for a snapshot (4x4)."""
    return (
        snapshot.camera.extrinsic_matrix()
        @ invert_transform(snapshot.T_dev_mount)
        @ invert_transform(np.asarray(T_world_dev, dtype=float))
    )


def project_loop(snapshot: Snapshot, T_world_dev: ArrayLike, T_world_obj: ArrayLike) -> FloatArray:
    """Pixels of the snapshot's object points through the whole loop (equation 31)."""
    T_cam_obj = camera_from_world(snapshot, T_world_dev) @ np.asarray(T_world_obj, dtype=float)
    return snapshot.camera.with_extrinsic_matrix(T_cam_obj).project(snapshot.points_obj)


def solve_object_pose(
    snapshots: Sequence[Snapshot],
    T_world_dev: ArrayLike,
    initial_T_world_obj: ArrayLike | None = None,
) -> PoseResult:
    """``T_world_obj`` from snapshots with the device pose known (``PoseResult.T``)."""
    views = [
        View(
            s.camera.with_extrinsic_matrix(camera_from_world(s, T_world_dev)),
            s.points_obj,
            s.pixels,
        )
        for s in snapshots
    ]
    return solve_npnp(views, initial_T_world_obj)


def solve_device_pose(
    snapshots: Sequence[Snapshot],
    T_world_obj: ArrayLike,
    initial_T_world_dev: ArrayLike | None = None,
) -> PoseResult:
    """``T_world_dev`` from snapshots of a known object (``PoseResult.T``; residuals as solved)."""
    views = []
    for s in snapshots:
        T_cam_dev = s.camera.extrinsic_matrix() @ invert_transform(s.T_dev_mount)
        points_world = transform_points(T_world_obj, s.points_obj)
        views.append(View(s.camera.with_extrinsic_matrix(T_cam_dev), points_world, s.pixels))
    initial = None if initial_T_world_dev is None else invert_transform(initial_T_world_dev)
    T_dev_world = solve_npnp(views, initial)
    T = invert_transform(T_dev_world.T)
    return PoseResult(
        T[:3, :3], T[:3, 3], T_dev_world.rms_px, T_dev_world.residuals, T_dev_world.iterations
    )
