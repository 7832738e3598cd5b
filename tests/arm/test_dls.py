"""Damped least squares: exact away from singularities, bounded through them, rate-limited."""

from __future__ import annotations

import numpy as np
import pytest

from umbra.modules.arm.dh import puma560
from umbra.modules.arm.dls import DLSSettings, adaptive_damping, scale_to_limits, solve_dls
from umbra.modules.arm.jacobian import jacobian

PUMA = puma560()
UNLIMITED = np.full(6, np.inf)


DEFAULT_SETTINGS = DLSSettings()


def solve(q, twist, settings=DEFAULT_SETTINGS, qd_max=UNLIMITED):
    return solve_dls(jacobian(PUMA, q), twist, q, PUMA.q_min, PUMA.q_max, qd_max, settings)


def test_away_from_singularities_dls_is_the_exact_inverse():
    rng = np.random.default_rng(0)
    q = np.radians([10, 45, -160, 20, 45, 30])
    J = jacobian(PUMA, q)
    for _ in range(20):
        twist = rng.normal(size=6) * 0.05
        result = solve(q, twist)
        assert result.damping == 0.0
        assert not result.near_singularity
        np.testing.assert_allclose(J @ result.rates, twist, atol=1e-10)
        np.testing.assert_allclose(result.rates, np.linalg.solve(J, twist), atol=1e-10)


def test_damping_law_rises_smoothly_below_eps():
    assert adaptive_damping(0.05, eps=0.04, lambda_max=0.1) == 0.0
    assert adaptive_damping(0.04, eps=0.04, lambda_max=0.1) == 0.0
    assert adaptive_damping(0.0, eps=0.04, lambda_max=0.1) == pytest.approx(0.1)
    assert adaptive_damping(0.02, eps=0.04, lambda_max=0.1) == pytest.approx(0.1 * np.sqrt(0.75))


def test_rates_stay_bounded_through_the_wrist_singularity():
    # Sweep q5 through 0 (joints 4 and 6 aligned) asking for a rotation about the flange's
    # x axis, the direction the wrist loses at q5 = 0.
    settings = DLSSettings(eps=0.04, lambda_max=0.04)
    base = np.radians([0, 45, -180, 20, 0, 0])
    peak_dls, peak_pinv = 0.0, 0.0
    for q5 in np.linspace(-0.2, 0.2, 401):
        q = base.copy()
        q[4] = q5
        J = jacobian(PUMA, q)
        R = PUMA.fk(q)[:3, :3]
        twist = np.r_[0.0, 0.0, 0.0, R @ [0.05, 0.0, 0.0]]
        result = solve(q, twist, settings)
        assert np.all(np.isfinite(result.rates))
        peak_dls = max(peak_dls, float(np.max(np.abs(result.rates))))
        if abs(q5) > 1e-9:
            peak_pinv = max(peak_pinv, float(np.max(np.abs(np.linalg.pinv(J) @ twist))))
        if abs(q5) < 0.01:
            assert result.near_singularity and result.damping > 0
    # The bound of DLS: each singular-direction gain is at most 1 / (2 lambda_max).
    assert peak_dls <= np.linalg.norm([0.05]) / (2 * settings.lambda_max) * 1.001
    assert peak_pinv > 20 * peak_dls  # the undamped inverse blows up near q5 = 0


def test_rate_limits_scale_the_whole_vector_and_keep_direction():
    rates, scale = scale_to_limits([2.0, -1.0, 0.5], [1.0, 1.0, 1.0])
    np.testing.assert_allclose(rates, [1.0, -0.5, 0.25])
    assert scale == 0.5
    q = np.radians([10, 45, -160, 20, 45, 30])
    twist = np.array([2.0, -1.2, 0.8, 0.0, 0.0, 0.0])  # too fast for the Puma's rate limits
    free = solve(q, twist)
    limited = solve(q, twist, qd_max=PUMA.qd_max)
    assert limited.scale < 1.0
    assert np.all(np.abs(limited.rates) <= PUMA.qd_max + 1e-12)
    np.testing.assert_allclose(limited.rates, free.rates * limited.scale)
    # The tool still moves along the asked direction, only slower.
    J = jacobian(PUMA, q)
    moved = J @ limited.rates
    np.testing.assert_allclose(
        moved / np.linalg.norm(moved), twist / np.linalg.norm(twist), atol=1e-12
    )


def test_near_limit_is_flagged_only_when_moving_towards_the_limit():
    q = np.radians([158, 45, -160, 20, 45, 30])  # joint 1 two degrees from its +160 limit
    J = jacobian(PUMA, q)
    towards = J @ np.array([0.1, 0, 0, 0, 0, 0])
    away = -towards
    result = solve(q, towards)
    assert result.near_limit and result.near_limit_joints == (0,)
    assert not solve(q, away).near_limit
