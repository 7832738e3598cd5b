"""A camera mount that is off: the simulation's way to put a camera where it is not believed.

The true pose of a mounted frame is the believed (nominal) pose followed by a small offset in
the mounted frame's own axes: ``T_parent_true = T_parent_nominal . T_nominal_true``. The offset
is given at the user's edge as ``xyz_m`` (metres) and ``rpy_deg`` (fixed-axis roll, pitch, yaw,
degrees) and converted once.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from umbra.modules.geometry.transforms import transform_from_xyz_rpy_deg

FloatArray = NDArray[np.float64]


def offset_transform(xyz_m: ArrayLike, rpy_deg: ArrayLike) -> FloatArray:
    """``T_nominal_true`` (4x4) from a translation in metres and roll-pitch-yaw in degrees."""
    xyz = np.asarray(xyz_m, dtype=float).reshape(3)
    rpy = np.asarray(rpy_deg, dtype=float).reshape(3)
    if not (np.all(np.isfinite(xyz)) and np.all(np.isfinite(rpy))):
        raise ValueError(f"mount offset must be finite, got xyz {xyz} rpy_deg {rpy}")
    return transform_from_xyz_rpy_deg(xyz, rpy)


def offset_mount(T_parent_nominal: ArrayLike, T_nominal_true: ArrayLike) -> FloatArray:
    """The true pose ``T_parent_true = T_parent_nominal . T_nominal_true`` (4x4)."""
    return np.asarray(T_parent_nominal, dtype=float) @ np.asarray(T_nominal_true, dtype=float)
