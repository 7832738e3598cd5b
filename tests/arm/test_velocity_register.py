"""REG_VEL logic: the watchdog drops to zero and says why; clamps keep direction."""

from __future__ import annotations

import numpy as np
import pytest

from umbra.connectors.errors import UserError
from umbra.connectors.states import GuardReason
from umbra.modules.arm.reg_vel import RegVel
from umbra.modules.arm.velocity_register import RegisterSettings, VelocityRegister
from umbra.modules.geometry.transforms import clamp_twist
from umbra.runtime.harness import ModuleHarness

SETTINGS = RegisterSettings(timeout=0.2, max_linear=0.1, max_angular=0.5)


def test_passes_a_fresh_command_and_zeroes_it_after_the_timeout():
    register = VelocityRegister(SETTINGS)
    command = np.array([0.01, 0.02, -0.03, 0.0, 0.0, 0.1])
    register.put(command, stamp=1.0)
    out = register.output(now=1.1)
    assert out.passing
    np.testing.assert_array_equal(out.twist, command)
    assert out.age == pytest.approx(0.1)
    out = register.output(now=1.2)  # exactly the timeout: still accepted
    assert out.passing
    out = register.output(now=1.2001)
    assert not out.passing
    np.testing.assert_array_equal(out.twist, np.zeros(6))
    assert "(link watchdog 0.200 s)" in out.zero_reason
    assert out.code == GuardReason.WATCHDOG


def test_zero_before_any_command_and_when_the_producer_is_gone():
    register = VelocityRegister(SETTINGS)
    assert register.output(now=0.0).zero_reason == "no command received yet"
    register.put(np.r_[0.01, 0, 0, 0, 0, 0], stamp=0.0)
    out = register.output(now=0.01, producer_alive=False)
    assert out.zero_reason == "command producer is gone"
    assert not np.any(out.twist)
    out = register.output(now=0.01, halt="snake failure: outside outer rectangle")
    assert out.zero_reason.startswith("snake failure") and out.code == GuardReason.HALTED
    register.clear()
    assert register.output(now=0.01).zero_reason == "no command received yet"


def test_bad_command_is_rejected_not_held():
    register = VelocityRegister(SETTINGS)
    register.put(np.r_[0.01, 0, 0, 0, 0, 0], stamp=0.0)
    register.put([np.nan, 0, 0, 0, 0, 0], stamp=0.05)
    out = register.output(now=0.06)
    assert "command rejected" in out.zero_reason and out.code == GuardReason.REJECTED
    assert not np.any(out.twist)


def test_clamps_scale_linear_and_angular_parts_keeping_direction():
    register = VelocityRegister(SETTINGS)
    register.put([0.3, 0.4, 0.0, 0.0, 0.0, -2.0], stamp=0.0)
    out = register.output(now=0.0)
    assert out.passing and out.clamped
    np.testing.assert_allclose(out.twist, [0.06, 0.08, 0.0, 0.0, 0.0, -0.5])
    twist, clamped = clamp_twist([0.01, 0, 0, 0, 0.1, 0], 0.1, 0.5)
    assert not clamped
    np.testing.assert_array_equal(twist, [0.01, 0, 0, 0, 0.1, 0])


def test_settings_are_validated_by_the_modules_declaration():
    """The register's bounds live in REG_VEL's ``Params`` (the settings are built from it)."""
    with pytest.raises(UserError, match="timeout"):
        ModuleHarness(RegVel, {"timeout": 0.0})


def test_a_fresh_arrival_made_from_old_sensor_data_is_refused_in_operator_words():
    """The defect of a starved vision process: a command computed now from an image 1.3 s old
    arrives on time, and the register must refuse it all the same."""
    register = VelocityRegister(SETTINGS)  # max_origin_age 0.25 s
    register.put(np.r_[0.02, 0, 0, 0, 0, 0], stamp=10.0, origin=8.7)
    out = register.output(now=10.001)
    assert not out.passing and out.stale
    np.testing.assert_array_equal(out.twist, np.zeros(6))
    assert out.zero_reason == "command made from sensor data 1.30 s old (limit 0.25 s)"
    assert out.code == GuardReason.STALE_DATA
    assert out.origin_age == pytest.approx(1.301)
    register.put(np.r_[0.02, 0, 0, 0, 0, 0], stamp=10.01, origin=9.9)  # fresh data again
    out = register.output(now=10.02)
    assert out.passing and not out.stale and out.origin_age == pytest.approx(0.12)


def test_a_held_command_goes_to_zero_when_its_data_grows_older_than_the_bound():
    register = VelocityRegister(SETTINGS)
    register.put(np.r_[0.02, 0, 0, 0, 0, 0], stamp=1.0, origin=0.9)
    assert register.output(now=1.15).passing  # data 0.25 s old: at the bound
    out = register.output(now=1.1501)
    assert out.stale and "0.25 s old" in out.zero_reason


def test_a_command_that_cannot_be_dated_is_old():
    register = VelocityRegister(SETTINGS)
    register.put(np.r_[0.02, 0, 0, 0, 0, 0], stamp=1.0, origin=-np.inf)
    out = register.output(now=1.0)
    assert out.stale
    assert out.zero_reason == "command made from sensor data that cannot be dated (limit 0.25 s)"
    assert out.code == GuardReason.UNDATABLE
