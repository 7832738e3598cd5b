"""The 4-DOF image-moment servo law: camera twist from feature errors.

Features ``s = (x_n, y_n, a_n, alpha)`` (see :mod:`umbra.modules.servo.features`) are driven by the
camera velocity ``u = (vx, vy, vz, wz)`` (camera frame: x right, y down, z along the optical
axis) through ``ds/dt = L u`` with, for a planar patch parallel to the image plane,
(Tahri and Chaumette 2005, restricted to these four degrees of freedom)::

        vx   vy   vz   wz
    L = [-1,   0,   0,  y_n]    x_n
        [ 0,  -1,   0, -x_n]    y_n
        [ 0,   0,  -1,   0 ]    a_n
        [ 0,   0,   0,  -1 ]    alpha

(a camera moving +x sees the patch move -x; turning about +z turns the image by -wz). The law
is ``u = -Lambda L^+ e`` with ``e = s - s*`` (roll error wrapped into (-pi/2, pi/2]), per-axis
gains ``Lambda`` (1/s), and saturation of the linear speed (norm) and of ``|wz|``. The result is
a 6-vector twist ``[vx, vy, vz, 0, 0, wz]`` in the camera frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from umbra.modules.geometry.polygon_moments import wrap_axis_angle
from umbra.modules.geometry.transforms import clamp_twist
from umbra.modules.servo.features import MomentFeatures

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class ServoGains:
    """Per-axis gains (1/s) for ``x, y, z, roll`` and speed limits (m/s, rad/s), built from
    validated parameters (vsServo's ``Params`` holds their bounds), not checked again here."""

    gains: tuple[float, float, float, float] = (0.8, 0.8, 0.6, 0.8)
    max_linear: float = 0.05
    max_angular: float = 0.3


def interaction_matrix(features: MomentFeatures) -> FloatArray:
    """4x4 interaction matrix of ``(x_n, y_n, a_n, alpha)`` w.r.t. ``(vx, vy, vz, wz)``."""
    return np.array(
        [
            [-1.0, 0.0, 0.0, features.y_n],
            [0.0, -1.0, 0.0, -features.x_n],
            [0.0, 0.0, -1.0, 0.0],
            [0.0, 0.0, 0.0, -1.0],
        ]
    )


def feature_error(features: MomentFeatures, goal: MomentFeatures) -> FloatArray:
    """``e = s - s*`` with the roll part wrapped into (-pi/2, pi/2]."""
    e = features.as_array() - goal.as_array()
    e[3] = wrap_axis_angle(e[3])
    return e


def servo_twist(
    features: MomentFeatures,
    goal: MomentFeatures,
    gains: ServoGains = ServoGains(),
) -> tuple[FloatArray, FloatArray]:
    """Camera twist ``[vx, vy, vz, 0, 0, wz]`` (m/s, rad/s; camera frame) and the error ``e``."""
    e = feature_error(features, goal)
    L = interaction_matrix(features)
    # L is square and invertible (det 1) on these four axes, so L^+ e = L^-1 e.
    u = -np.asarray(gains.gains) * np.linalg.solve(L, e)
    twist = np.array([u[0], u[1], u[2], 0.0, 0.0, u[3]])
    return clamp_twist(twist, gains.max_linear, gains.max_angular)[0], e
