"""Homogeneous transforms and twists (metres, radians).

Conventions:

* ``T_a_b`` is the 4x4 pose of frame ``b`` in frame ``a``: it maps a point's coordinates in ``b``
  to its coordinates in ``a`` (``p_a = T_a_b @ p_b``), and ``T_a_b @ T_b_c = T_a_c``.
* A twist is a 6-vector ``[v; w]``: ``v`` (m/s) is the velocity of the origin of the frame it is
  expressed in, ``w`` (rad/s) the angular velocity, both as coordinates in that frame (a *body*
  twist of that frame). Integrating a body twist ``xi`` of frame ``b`` for ``dt`` moves the frame
  to ``T_a_b @ exp(hat(xi) dt)``.

Every rotation conversion (Euler angles, axis-angle) goes through :class:`scipy.spatial.transform.
Rotation`, imported by the functions that use it (importing this module loads no scipy: ``umbra
check`` reads module declarations that import it); plain matrix products and inverses are written
with numpy so they stay cheap enough for the servo tick.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]


class TransformError(ValueError):
    """An array that should be a rotation, a transform or a twist is not one."""


def _check_shape(name: str, array: FloatArray, shape: tuple[int, ...]) -> FloatArray:
    if array.shape != shape:
        raise TransformError(f"{name} must have shape {shape}, got {array.shape}")
    if not np.all(np.isfinite(array)):
        raise TransformError(f"{name} must be finite, got {array.tolist()}")
    return array


def transform_from_rotation_translation(R: ArrayLike, t: ArrayLike) -> FloatArray:
    """4x4 transform from a 3x3 rotation ``R`` and a translation ``t`` (metres)."""
    R = _check_shape("R", np.asarray(R, dtype=float), (3, 3))
    t = _check_shape("t", np.asarray(t, dtype=float).reshape(-1), (3,))
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = t
    return T


def translation(x: float, y: float, z: float) -> FloatArray:
    """Pure translation by ``(x, y, z)`` metres (Paul's ``Trans(x, y, z)``)."""
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


def rotation_about_axis(axis: str, angle: float) -> FloatArray:
    """4x4 pure rotation by ``angle`` (rad) about ``axis`` ``"x"``, ``"y"`` or ``"z"``."""
    if axis not in ("x", "y", "z"):
        raise TransformError(f"axis must be 'x', 'y' or 'z', got {axis!r}")
    from scipy.spatial.transform import Rotation

    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler(axis, angle).as_matrix()
    return T


def rot_x(angle: float) -> FloatArray:
    """``Rot_x(angle)``: 4x4 rotation about x by ``angle`` (rad)."""
    return rotation_about_axis("x", angle)


def rot_y(angle: float) -> FloatArray:
    """``Rot_y(angle)``: 4x4 rotation about y by ``angle`` (rad)."""
    return rotation_about_axis("y", angle)


def rot_z(angle: float) -> FloatArray:
    """``Rot_z(angle)``: 4x4 rotation about z by ``angle`` (rad)."""
    return rotation_about_axis("z", angle)


def compose(*transforms: ArrayLike) -> FloatArray:
    """Product ``T1 @ T2 @ ... @ Tn`` of 4x4 transforms (identity when none are given)."""
    result = np.eye(4)
    for T in transforms:
        result = result @ np.asarray(T, dtype=float)
    return result


def invert_transform(T: ArrayLike) -> FloatArray:
    """Inverse of a rigid 4x4 transform: ``T_b_a`` from ``T_a_b`` (uses ``R^T``, not a solve)."""
    T = np.asarray(T, dtype=float)
    R = T[:3, :3]
    inverse = np.eye(4)
    inverse[:3, :3] = R.T
    inverse[:3, 3] = -R.T @ T[:3, 3]
    return inverse


def transform_points(T_a_b: ArrayLike, points_b: ArrayLike) -> FloatArray:
    """Coordinates in frame ``a`` of points ``(3,)`` or ``(n, 3)`` given in frame ``b``."""
    T = np.asarray(T_a_b, dtype=float)
    p = np.asarray(points_b, dtype=float)
    return p @ T[:3, :3].T + T[:3, 3]


def is_orthonormal_transform(T: ArrayLike, tolerance: float = 1e-9) -> bool:
    """True when ``T`` is a finite 4x4 with orthonormal axes (a rotation or a reflection, det
    +-1) and last row ``[0, 0, 0, 1]``, each within ``tolerance``."""
    T = np.asarray(T, dtype=float)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        return False
    R = T[:3, :3]
    return bool(
        np.allclose(R.T @ R, np.eye(3), atol=tolerance)
        and np.allclose(T[3], (0.0, 0.0, 0.0, 1.0), atol=tolerance)
    )


def is_rigid(T: ArrayLike, tolerance: float = 1e-9) -> bool:
    """True when ``T`` is a 4x4 rigid transform: orthonormal, det +1, last row ``[0, 0, 0, 1]``."""
    if not is_orthonormal_transform(T, tolerance):
        return False
    return bool(abs(np.linalg.det(np.asarray(T, dtype=float)[:3, :3]) - 1.0) < tolerance)


def transform_from_xyz_rpy_deg(xyz: ArrayLike, rpy_deg: ArrayLike) -> FloatArray:
    """Transform from a user-edge translation (metres) and roll-pitch-yaw in degrees.

    ``rpy_deg`` = (roll about x, pitch about y, yaw about z), applied as fixed axes x, then y,
    then z (``R = Rz(yaw) Ry(pitch) Rx(roll)``, the URDF/ROS convention).
    """
    from scipy.spatial.transform import Rotation

    R = Rotation.from_euler("xyz", np.asarray(rpy_deg, dtype=float), degrees=True).as_matrix()
    return transform_from_rotation_translation(R, xyz)


def xyz_rpy_deg_from_transform(T: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Inverse of :func:`transform_from_xyz_rpy_deg`: ``(xyz metres, rpy_deg)``."""
    from scipy.spatial.transform import Rotation

    T = np.asarray(T, dtype=float)
    rpy = Rotation.from_matrix(T[:3, :3]).as_euler("xyz", degrees=True)
    return T[:3, 3].copy(), rpy


def cross3(a: ArrayLike, b: ArrayLike) -> FloatArray:
    """Cross product of 3-vectors (or stacks ``(..., 3)``); ``numpy.cross`` without its overhead."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out


def skew(v: ArrayLike) -> FloatArray:
    """3x3 cross-product matrix ``[v]x`` with ``[v]x @ u == cross(v, u)``."""
    x, y, z = np.asarray(v, dtype=float)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def twist_adjoint(T_a_b: ArrayLike) -> FloatArray:
    """6x6 adjoint of ``T_a_b`` for twists ordered ``[v; w]``.

    Maps a body twist of frame ``b`` (coordinates in ``b``) to the twist of the *same rigid
    motion* seen at frame ``a``'s origin with coordinates in ``a``, where ``a`` is rigidly
    attached to ``b``: ``w_a = R w_b``, ``v_a = R v_b + p x (R w_b)`` with ``R, p`` the rotation
    and translation of ``T_a_b``.
    """
    T = np.asarray(T_a_b, dtype=float)
    R = T[:3, :3]
    Ad = np.zeros((6, 6))
    Ad[:3, :3] = R
    Ad[3:, 3:] = R
    Ad[:3, 3:] = skew(T[:3, 3]) @ R
    return Ad


def twist_tool_from_camera(T_tool_camera: ArrayLike, camera_twist: ArrayLike) -> FloatArray:
    """Tool-frame twist that moves a rigid tool-camera body as ``camera_twist`` asks.

    Args:
        T_tool_camera: pose of the camera in the tool frame (4x4, metres).
        camera_twist: ``[v; w]`` of the camera (m/s, rad/s) in camera coordinates.

    Returns:
        ``[v; w]`` of the tool frame in tool coordinates: ``w_tool = R w_cam`` and
        ``v_tool = R v_cam + w_tool x (p_tool - p_cam)``, the lever-arm term that keeps the
        camera's own motion right when it is offset from the tool point (``p_cam`` = camera
        origin, ``p_tool`` = 0 in tool coordinates).
    """
    T = np.asarray(T_tool_camera, dtype=float)
    xi = np.asarray(camera_twist, dtype=float).reshape(-1)
    if xi.shape != (6,):
        raise TransformError(f"camera_twist must have 6 entries [v; w], got {xi.shape}")
    R = T[:3, :3]
    w_tool = R @ xi[3:]
    v_tool = R @ xi[:3] + cross3(w_tool, -T[:3, 3])
    return np.concatenate([v_tool, w_tool])


def twist_camera_from_tool(T_tool_camera: ArrayLike, tool_twist: ArrayLike) -> FloatArray:
    """Inverse of :func:`twist_tool_from_camera`: the camera's twist for a tool twist."""
    return twist_tool_from_camera(invert_transform(T_tool_camera), tool_twist)


def clamp_twist(twist: ArrayLike, max_linear: float, max_angular: float) -> tuple[FloatArray, bool]:
    """Scale the linear and the angular part of ``[v; w]`` to at most the given norms.

    Each part is scaled as a vector, so its direction is kept. Returns a new twist and whether
    either limit scaled it.
    """
    xi = np.array(twist, dtype=float).reshape(6)
    clamped = False
    for part, limit in ((slice(0, 3), max_linear), (slice(3, 6), max_angular)):
        norm = float(np.linalg.norm(xi[part]))
        if norm > limit:
            xi[part] *= limit / norm
            clamped = True
    return xi, clamped


def twist_matrix(twist: ArrayLike) -> FloatArray:
    """4x4 ``hat(xi)`` of a twist ``[v; w]``: ``[[ [w]x, v ], [0, 0]]``."""
    xi = np.asarray(twist, dtype=float).reshape(-1)
    hat = np.zeros((4, 4))
    hat[:3, :3] = skew(xi[3:])
    hat[:3, 3] = xi[:3]
    return hat


def twist_exponential(twist: ArrayLike, dt: float) -> FloatArray:
    """``exp(hat(xi) dt)``: the rigid motion of constant twist ``xi`` over ``dt`` seconds.

    Closed form: the rotation from the rotation vector ``w dt`` (scipy), the translation
    ``V v dt`` with ``V = I + (1 - cos t)/t^2 K + (t - sin t)/t^3 K^2``, ``K = [w dt]x``,
    ``t = |w dt|`` (series near ``t = 0``). Agrees with ``scipy.linalg.expm`` of the 4x4.
    """
    from scipy.spatial.transform import Rotation

    xi = np.asarray(twist, dtype=float).reshape(6) * dt
    rotvec = xi[3:]
    theta = float(np.linalg.norm(rotvec))
    K = skew(rotvec)
    if theta < 1e-6:
        c1, c2 = 0.5 - theta**2 / 24.0, 1.0 / 6.0 - theta**2 / 120.0
    else:
        c1 = (1.0 - np.cos(theta)) / theta**2
        c2 = (theta - np.sin(theta)) / theta**3
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    T[:3, 3] = (np.eye(3) + c1 * K + c2 * (K @ K)) @ xi[:3]
    return T


def twist_exponential_expm(twist: ArrayLike, dt: float) -> FloatArray:
    """``exp(hat(xi) dt)`` by the general matrix exponential (reference for tests)."""
    from scipy.linalg import expm

    return expm(twist_matrix(twist) * dt)


def integrate_body_twist(T_a_b: ArrayLike, body_twist: ArrayLike, dt: float) -> FloatArray:
    """Pose of frame ``b`` after moving with constant body twist ``body_twist`` for ``dt`` s."""
    return np.asarray(T_a_b, dtype=float) @ twist_exponential(body_twist, dt)
