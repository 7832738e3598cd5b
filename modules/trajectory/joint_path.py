"""A joint path ``q(s)`` through planned waypoints: a C2 cubic spline per joint.

``s`` is the planner's path parameter (increasing, path units); ``q`` in radians (or metres for
prismatic joints). The spline is not-a-knot, so ``q``, ``dq/ds`` and ``d2q/ds2`` are continuous:
a continuous ``s_dot`` then gives continuous joint velocities.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]


class JointPath:
    """``q(s)`` and its derivatives over ``[0, length]`` from waypoints ``(s_i, q_i)``."""

    def __init__(self, s: ArrayLike, joints: ArrayLike) -> None:
        from scipy.interpolate import CubicSpline

        s_arr = np.asarray(s, dtype=float)
        q = np.asarray(joints, dtype=float)
        if s_arr.ndim != 1 or q.ndim != 2 or q.shape[0] != s_arr.size or s_arr.size < 2:
            raise ValueError(
                f"a joint path needs N >= 2 parameters and N x n joints, got {s_arr.shape} and "
                f"{q.shape}"
            )
        if not (np.all(np.isfinite(s_arr)) and np.all(np.isfinite(q))):
            raise ValueError("a joint path's parameters and joints must be finite")
        if s_arr[0] != 0.0 or np.any(np.diff(s_arr) <= 0):
            raise ValueError("a joint path's parameter must start at 0 and increase strictly")
        self.s = s_arr
        self.joints = q
        self.length = float(s_arr[-1])
        self._spline = CubicSpline(
            s_arr, q, axis=0, bc_type="natural" if s_arr.size < 4 else "not-a-knot"
        )

    def q(self, s: float | ArrayLike) -> FloatArray:
        """Joint positions at ``s`` (clipped to the path)."""
        return self._spline(np.clip(s, 0.0, self.length))

    def dq_ds(self, s: float | ArrayLike) -> FloatArray:
        """Joint tangent at ``s`` (joint units per path unit)."""
        return self._spline(np.clip(s, 0.0, self.length), 1)

    def d2q_ds2(self, s: float | ArrayLike) -> FloatArray:
        """Joint curvature at ``s`` (joint units per path unit²)."""
        return self._spline(np.clip(s, 0.0, self.length), 2)

    def nearest_s(
        self,
        q: ArrayLike,
        samples: int = 400,
        around: float | None = None,
        window: float = np.inf,
    ) -> float:
        """The path parameter whose joints are nearest ``q`` (dense sampling, Euclidean), over
        the whole path or within ``window`` of ``around`` (path units)."""
        low, high = 0.0, self.length
        if around is not None:
            low, high = max(0.0, around - window), min(self.length, around + window)
        grid = np.linspace(low, high, samples)
        return float(grid[np.argmin(np.linalg.norm(self.q(grid) - np.asarray(q), axis=1))])
