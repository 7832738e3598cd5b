"""Between the calibration math's :class:`PinholeCamera` and the ``CameraModel`` message.

``PinholeCamera`` extrinsics ``(R, d)`` take reference-frame points into the camera frame
(``T_cam_ref``); the message carries the camera's pose in its mount, ``T_mount_camera``, which is
the inverse. Distortion in the message is ``[k1, k2, p1, p2, k3]``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from umbra.connectors.messages import CameraModel
from umbra.modules.calib.camera_model import Intrinsics, PinholeCamera
from umbra.modules.calib.rotations import invert_transform


def camera_message(
    camera: PinholeCamera,
    *,
    zoom: float = 0.0,
    width: int = 640,
    height: int = 480,
    mount: str = "tool",
    frame: str = "camera",
    stamp: float = 0.0,
) -> CameraModel:
    """A ``CameraModel`` message whose mount is the frame ``camera``'s extrinsics start from."""
    f = camera.intrinsics
    return CameraModel(
        stamp=stamp,
        fx=f.fx,
        fy=f.fy,
        skew=f.skew,
        u0=f.u0,
        v0=f.v0,
        dist=camera.distortion.copy(),
        width=width,
        height=height,
        T_mount_camera=invert_transform(camera.extrinsic_matrix()),
        mount=mount,
        frame=frame,
        zoom=float(zoom),
    )


def pinhole_from_message(
    message: CameraModel, T_ref_mount: ArrayLike | None = None
) -> PinholeCamera:
    """The camera of a message, with extrinsics relative to frame ``ref`` given ``T_ref_mount``
    (the mount's pose in ``ref``; identity: extrinsics relative to the mount)."""
    T_ref_camera = np.asarray(message.T_mount_camera, dtype=float)
    if T_ref_mount is not None:
        T_ref_camera = np.asarray(T_ref_mount, dtype=float) @ T_ref_camera
    camera = PinholeCamera(Intrinsics.of_model(message), distortion=message.dist)
    return camera.with_extrinsic_matrix(invert_transform(T_ref_camera))
