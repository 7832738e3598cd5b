"""Joint units (rad, rad/s) to drive units (counts, counts/s) and back.

A joint's drive reports position in counts; `counts_per_rad` converts (its sign sets the
direction) and `zero_counts` is the count at joint angle 0. Velocities use the same scale
per second (CiA 402 velocity units = position units per second).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

INT32_MIN = -(1 << 31)
INT32_MAX = (1 << 31) - 1


def rates_to_counts_s(rates_rad_s: ArrayLike, counts_per_rad: ArrayLike) -> NDArray[np.int64]:
    """Joint rates (rad/s) to target velocities (counts/s), rounded and clamped to int32."""
    counts = np.rint(np.asarray(rates_rad_s, dtype=float) * np.asarray(counts_per_rad, dtype=float))
    return np.clip(counts, INT32_MIN, INT32_MAX).astype(np.int64)


def counts_to_angles(
    counts: ArrayLike, counts_per_rad: ArrayLike, zero_counts: ArrayLike = 0
) -> NDArray[np.float64]:
    """Position actual values (counts) to joint angles (rad)."""
    return (np.asarray(counts, dtype=float) - np.asarray(zero_counts, dtype=float)) / np.asarray(
        counts_per_rad, dtype=float
    )


def counts_s_to_rates(counts_s: ArrayLike, counts_per_rad: ArrayLike) -> NDArray[np.float64]:
    """Velocity actual values (counts/s) to joint rates (rad/s)."""
    return np.asarray(counts_s, dtype=float) / np.asarray(counts_per_rad, dtype=float)


def angles_to_counts(
    angles_rad: ArrayLike, counts_per_rad: ArrayLike, zero_counts: ArrayLike = 0
) -> NDArray[np.float64]:
    """Joint angles (rad) to position counts (unrounded)."""
    return np.asarray(angles_rad, dtype=float) * np.asarray(
        counts_per_rad, dtype=float
    ) + np.asarray(zero_counts, dtype=float)
