"""Camera poses that look at a point (m, base frame), for placing and checking aimed cameras."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]


def look_at(eye: ArrayLike, target: ArrayLike, up: ArrayLike = (0.0, 0.0, 1.0)) -> FloatArray:
    """``T_base_camera`` of a camera at ``eye`` whose optic axis (+z) points at ``target``, with
    its image's "up" (-y) as close to ``up`` as possible (x right). Metres, base frame."""
    eye_v = np.asarray(eye, dtype=float)
    z = np.asarray(target, dtype=float) - eye_v
    if np.linalg.norm(z) < 1e-9:
        raise ValueError(f"look_at: target {target!s} coincides with the eye {eye!s}")
    z = z / np.linalg.norm(z)
    x = np.cross(z, -np.asarray(up, dtype=float))
    if np.linalg.norm(x) < 1e-9:
        raise ValueError(f"look_at: the view direction {z} is parallel to up {up!s}")
    x = x / np.linalg.norm(x)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    T[:3, 3] = eye_v
    return T
