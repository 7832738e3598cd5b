"""Conversions between joint units (rad, rad/s) and drive counts."""

from __future__ import annotations

import numpy as np

from umbra.modules.arm.cia402.units import (
    INT32_MAX,
    INT32_MIN,
    angles_to_counts,
    counts_s_to_rates,
    counts_to_angles,
    rates_to_counts_s,
)


def test_angles_round_trip_through_counts_with_offset_and_sign() -> None:
    cpr = np.array([10_000.0, -4096.0 / (2 * np.pi), 524288.0 / np.pi])
    zero = np.array([0, 1500, -7])
    q = np.array([0.3, -1.2, 2.5])
    counts = np.rint(angles_to_counts(q, cpr, zero))
    back = counts_to_angles(counts, cpr, zero)
    assert np.all(np.abs(back - q) <= 0.5 / np.abs(cpr))


def test_rates_round_to_counts_and_clamp_to_int32() -> None:
    counts = rates_to_counts_s([0.12345, -1.0, 1e9, -1e9], 10_000.0)
    assert counts.tolist() == [1234, -10_000, INT32_MAX, INT32_MIN]
    np.testing.assert_allclose(counts_s_to_rates(counts[:2], 10_000.0), [0.1234, -1.0])
