"""Damped least squares (DLS) resolved-rate control with adaptive damping and rate limits.

``qd = J^T (J J^T + lambda^2 I)^-1 xd``, computed from the SVD ``J = U S V^T`` as
``qd = sum_i s_i / (s_i^2 + lambda^2) (u_i . xd) v_i``. The damping rises only near a
singularity (Nakamura and Hanafusa; Maciejewski and Klein)::

    lambda^2 = 0                                            if s_min >= eps
    lambda^2 = lambda_max^2 (1 - (s_min / eps)^2)           if s_min <  eps

so away from singularities DLS is the exact inverse, and at one every gain ``s/(s^2+lambda^2)``
stays below ``1/(2 lambda_max)``: joint rates stay bounded. Rates over their limits are scaled
down *together* (one factor for the whole vector), which keeps the direction of motion.

Units: ``xd`` is a base-frame twist ``[v; w]`` (m/s, rad/s) at the tool point; rates in rad/s
(m/s for a prismatic joint). ``eps`` is a singular value of the Jacobian (mixed units, as J).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class DLSSettings:
    """Settings of the DLS solver.

    Attributes:
        eps: singular-value threshold below which damping starts (same units as J's).
        lambda_max: damping at ``s_min = 0`` (same units).
        limit_margin: distance from a joint limit (rad or m) at which ``near_limit`` is flagged.
    """

    eps: float = 0.04
    lambda_max: float = 0.04
    limit_margin: float = np.radians(5.0)

    def __post_init__(self) -> None:
        if not (self.eps > 0 and self.lambda_max > 0 and self.limit_margin >= 0):
            raise ValueError(
                f"DLS settings must be positive: eps={self.eps}, lambda_max={self.lambda_max}, "
                f"limit_margin={self.limit_margin}"
            )


@dataclass(frozen=True)
class DLSResult:
    """Joint rates from :func:`solve_dls` and what shaped them.

    Attributes:
        rates: joint rates after scaling (rad/s or m/s).
        damping: the ``lambda`` used.
        sigma_min: smallest singular value of J.
        scale: factor (<= 1) applied to the whole vector to respect rate limits.
        near_singularity: ``sigma_min < eps``.
        near_limit: some joint is within ``limit_margin`` of a limit and the rates drive it
            towards that limit.
        near_limit_joints: indices of those joints.
    """

    rates: FloatArray
    damping: float
    sigma_min: float
    scale: float
    near_singularity: bool
    near_limit: bool
    near_limit_joints: tuple[int, ...] = ()


def adaptive_damping(sigma_min: float, eps: float, lambda_max: float) -> float:
    """``lambda`` for the smallest singular value ``sigma_min`` (see module docstring)."""
    if sigma_min >= eps:
        return 0.0
    return float(lambda_max * np.sqrt(1.0 - (sigma_min / eps) ** 2))


def _pinv_gains(s: FloatArray) -> FloatArray:
    # Exact inverse where s is usable; zero for numerically null directions.
    cutoff = max(s.max(initial=0.0), 1.0) * 1e-12
    return np.divide(1.0, s, out=np.zeros_like(s), where=s > cutoff)


def scale_to_limits(rates: ArrayLike, qd_max: ArrayLike) -> tuple[FloatArray, float]:
    """Scale the whole rate vector so every ``|rate_i| <= qd_max_i``; returns ``(rates, scale)``."""
    rates = np.asarray(rates, dtype=float)
    ratio = np.max(np.abs(rates) / np.asarray(qd_max, dtype=float), initial=0.0)
    if ratio <= 1.0:
        return rates, 1.0
    scale = 1.0 / ratio
    return rates * scale, float(scale)


def solve_dls(
    J: ArrayLike,
    twist: ArrayLike,
    q: ArrayLike,
    q_min: ArrayLike,
    q_max: ArrayLike,
    qd_max: ArrayLike,
    settings: DLSSettings = DLSSettings(),
) -> DLSResult:
    """Joint rates that produce ``twist`` (base frame, tool point) as well as DLS can.

    Args:
        J: ``6 x n`` geometric Jacobian (base frame, rows ``[v; w]``).
        twist: desired ``[v; w]`` of the tool point, base coordinates.
        q: current joint values; ``q_min``, ``q_max`` limits; ``qd_max`` rate limits.
        settings: damping and flag thresholds.
    """
    J = np.asarray(J, dtype=float)
    twist = np.asarray(twist, dtype=float).reshape(-1)
    if twist.shape != (J.shape[0],):
        raise ValueError(f"twist must have {J.shape[0]} entries, got {twist.shape[0]}")
    U, s, Vt = np.linalg.svd(J, full_matrices=False)
    sigma_min = float(s[-1])
    damping = adaptive_damping(sigma_min, settings.eps, settings.lambda_max)
    gains = s / (s**2 + damping**2) if damping > 0 else _pinv_gains(s)
    rates = Vt.T @ (gains * (U.T @ twist))
    rates, scale = scale_to_limits(rates, qd_max)
    q = np.asarray(q, dtype=float)
    towards_min = (q - np.asarray(q_min) < settings.limit_margin) & (rates < 0)
    towards_max = (np.asarray(q_max) - q < settings.limit_margin) & (rates > 0)
    near = tuple(int(i) for i in np.flatnonzero(towards_min | towards_max))
    return DLSResult(
        rates=rates,
        damping=damping,
        sigma_min=sigma_min,
        scale=scale,
        near_singularity=sigma_min < settings.eps,
        near_limit=bool(near),
        near_limit_joints=near,
    )
