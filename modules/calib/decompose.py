"""Appendix B of the Sandia report: a camera matrix to intrinsics and extrinsics, and back.

Conventions (they make the decomposition unique):

* ``P ~ K [R | d]`` up to any nonzero scale, with ``K = [[fx, skew, u0], [0, fy, v0], [0, 0, 1]]``
  (pixels; the report's ``fxy`` is ``skew``), ``R`` a proper rotation (``det R = +1``) and ``d``
  in the units of the world points (metres in this project).
* The focal lengths ``fx`` and ``fy`` are positive. With ``det R = +1`` this fixes the sign of the
  scale: ``P`` is divided by ``sign(det M) |m3|`` where ``M`` is the left 3x3 block and ``m3`` its
  third row; then ``r3 = m3`` and ``dz = p34``.
* ``R`` and ``d`` take world points into the camera frame (``X_cam = R X + d``; x right, y down,
  z forward), so the camera centre is ``-R^T d`` and a point in front of the camera has
  ``r3 . X + dz > 0``. Points behind a decomposed camera mean the data came from a mirrored
  (left-handed) fit; :func:`umbra.modules.calib.dlt.dlt_camera_matrix` rejects those.

The computation is the report's Gram-Schmidt on the rows of ``M`` (equivalent to an RQ
factorization): ``v0 = m2.r3``, ``fy = |m2 - v0 r3|``, ``r2 = (m2 - v0 r3)/fy``, ``u0 = m1.r3``,
``skew = m1.r2``, ``fx = |m1 - skew r2 - u0 r3|``, ``r1 = (m1 - skew r2 - u0 r3)/fx`` and
``d = K^-1 p4``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from umbra.modules.calib.camera_model import Intrinsics
from umbra.modules.calib.errors import DegenerateGeometryError

FloatArray = NDArray[np.float64]


def compose_camera_matrix(intrinsics: Intrinsics, R: ArrayLike, d: ArrayLike) -> FloatArray:
    """``P = K [R | d]`` (3x4)."""
    Rd = np.hstack([np.asarray(R, dtype=float), np.asarray(d, dtype=float).reshape(3, 1)])
    return intrinsics.matrix() @ Rd


def normalize_camera_matrix(P: ArrayLike) -> FloatArray:
    """``P`` scaled so that ``|m3| = 1`` and ``det M > 0`` (the scale of ``K [R | d]``)."""
    P = np.asarray(P, dtype=float)
    if P.shape != (3, 4) or not np.all(np.isfinite(P)):
        raise DegenerateGeometryError(f"a camera matrix must be a finite 3x4 array, got {P.shape}")
    M = P[:, :3]
    det = np.linalg.det(M)
    scale = np.linalg.norm(M[2])
    if scale == 0 or abs(det) <= 1e-12 * np.linalg.norm(M) ** 3:
        raise DegenerateGeometryError("camera matrix has a singular left 3x3 block")
    return P / (np.sign(det) * scale)


def decompose_camera_matrix(P: ArrayLike) -> tuple[Intrinsics, FloatArray, FloatArray]:
    """Split a camera matrix into ``(intrinsics, R, d)`` with the conventions of this module."""
    Pn = normalize_camera_matrix(P)
    m1, m2, r3 = Pn[0, :3], Pn[1, :3], Pn[2, :3]
    v0 = float(m2 @ r3)
    row2 = m2 - v0 * r3
    fy = float(np.linalg.norm(row2))
    r2 = row2 / fy
    u0 = float(m1 @ r3)
    skew = float(m1 @ r2)
    row1 = m1 - skew * r2 - u0 * r3
    fx = float(np.linalg.norm(row1))
    r1 = row1 / fx
    R = np.vstack([r1, r2, r3])
    intrinsics = Intrinsics(fx, fy, skew, u0, v0)
    d = np.asarray(np.linalg.solve(intrinsics.matrix(), Pn[:, 3]), dtype=np.float64)
    return intrinsics, R, d
