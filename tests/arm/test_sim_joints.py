"""The simulated joints: rate and acceleration limits, lag, joint limits, calibration error."""

from __future__ import annotations

import numpy as np
import pytest

from umbra.connectors.errors import UserError
from umbra.modules.arm.dh import puma560
from umbra.modules.arm.joints_backend import SimJointsBackend
from umbra.modules.arm.sim_joints import SimJoints, SimJointSettings
from umbra.modules.arm.wolverine_jnts import WolverineJnts
from umbra.runtime.harness import ModuleHarness

PUMA = puma560()
Q0 = np.radians([0, 45, -180, 0, 45, 0])


def run(sim: SimJoints, rates, seconds: float, dt: float = 0.001) -> None:
    for _ in range(round(seconds / dt)):
        sim.step(rates, dt)


def test_constant_rate_integrates_after_the_lag():
    sim = SimJoints(PUMA, Q0, SimJointSettings(lag_tau=0.02, accel_max=100.0))
    rates = np.array([0.1, -0.2, 0.3, 0.0, 0.1, -0.1])
    run(sim, rates, 1.0)
    np.testing.assert_allclose(sim.qd, rates, atol=1e-9)
    # A first-order lag loses tau * rate of travel compared with an ideal integrator.
    np.testing.assert_allclose(sim.q_reported - Q0, rates * (1.0 - 0.02), atol=2e-4)


def test_lag_reaches_63_percent_after_one_time_constant():
    sim = SimJoints(PUMA, Q0, SimJointSettings(lag_tau=0.05, accel_max=1e6))
    run(sim, np.r_[1.0, np.zeros(5)], 0.05, dt=0.0005)
    assert sim.qd[0] == pytest.approx(1 - np.exp(-1), abs=1e-3)


def test_rate_and_acceleration_limits():
    sim = SimJoints(PUMA, Q0, SimJointSettings(lag_tau=0.0, accel_max=20.0))
    sim.step(np.full(6, 100.0), 0.01)
    np.testing.assert_allclose(sim.qd, 0.2)  # accel_max * dt
    run(sim, np.full(6, 100.0), 0.3, dt=0.01)
    np.testing.assert_allclose(sim.qd[3:], PUMA.qd_max[3:])  # clipped at each joint's limit


def test_joint_limits_clamp_and_stop_the_joint():
    start = Q0.copy()
    start[4] = np.radians(95)
    sim = SimJoints(PUMA, start, SimJointSettings(lag_tau=0.0, accel_max=50.0))
    run(sim, np.r_[0, 0, 0, 0, 1.0, 0], 1.0)
    assert sim.q_reported[4] == pytest.approx(PUMA.q_max[4])
    assert sim.qd[4] == 0.0
    run(sim, np.r_[0, 0, 0, 0, -1.0, 0], 0.1)  # it can leave the limit again
    assert sim.q_reported[4] < PUMA.q_max[4]


def test_calibration_error_separates_true_from_reported_angles():
    error = (0.01, -0.02, 0.015, 0.0, 0.0, 0.0)
    sim = SimJoints(PUMA, Q0, SimJointSettings(calibration_error=error))
    np.testing.assert_allclose(sim.q_true - sim.q_reported, error)
    run(sim, np.r_[0.1, 0, 0, 0, 0, 0], 0.5)
    np.testing.assert_allclose(sim.q_true - sim.q_reported, error, atol=1e-15)
    # The true flange is centimetres away from where the controller believes it is.
    miss = np.linalg.norm(PUMA.fk(sim.q_true)[:3, 3] - PUMA.fk(sim.q_reported)[:3, 3])
    assert 0.005 < miss < 0.05


def test_gripper_travels_in_its_travel_time():
    sim = SimJoints(PUMA, Q0, SimJointSettings(gripper_travel_time=0.5), gripper_opening=1.0)
    sim.command_gripper("close")
    run(sim, np.zeros(6), 0.25)
    assert sim.gripper_opening == pytest.approx(0.5, abs=1e-9)
    assert sim.gripper_moving
    run(sim, np.zeros(6), 0.3)
    assert sim.gripper_opening == 0.0
    assert not sim.gripper_moving
    with pytest.raises(ValueError, match="open' or 'close"):
        sim.command_gripper("squeeze")


def test_bad_setup_is_rejected_by_the_modules_declaration():
    """One offset per joint and a start inside the limits: WOLVERINE_JNTS's ``Params`` rule
    (the plant is built from validated parameters)."""
    with pytest.raises(UserError, match=r"calibration_error_deg`? needs 6"):
        ModuleHarness(WolverineJnts, {"calibration_error_deg": [0.1]})
    with pytest.raises(UserError, match="outside the joint limits: j3 180"):
        ModuleHarness(WolverineJnts, {"initial_q_deg": [0, 45, 180, 0, 45, 0]})


def commanded_backend(rate: float, watchdog: float = 0.1) -> tuple[SimJointsBackend, float]:
    """A sim backend whose joint 1 has run 1 s at ``rate`` (rad/s), commanded every 10 ms; and
    the time of its last command (s)."""
    settings = SimJointSettings(lag_tau=0.02, accel_max=8.0, watchdog=watchdog)
    backend = SimJointsBackend(PUMA, Q0, settings)
    backend.start()
    rates = np.r_[rate, np.zeros(5)]
    t = 0.0
    for _ in range(101):
        backend.read(t)
        backend.command(rates, t)
        t += 0.01
    return backend, t - 0.01


@pytest.mark.parametrize("gap_s", [1.0, 5.0, 3600.0])
def test_a_gap_between_steps_carries_the_command_for_the_watchdog_time_only(gap_s: float):
    rate = 0.5
    backend, t_last = commanded_backend(rate)
    before = backend.read(t_last).position[0]
    reading = backend.read(t_last + gap_s)  # the process was stopped for gap_s
    travel = reading.position[0] - before
    # 0.1 s at the held rate, then the stop through the 20 ms lag and the 8 rad/s^2 limit:
    # between rate * watchdog and rate * (watchdog + lag) + rate^2 / (2 accel); on a drive
    # without its own watchdog it was rate * gap_s (0.5 rad in 1 s).
    assert rate * 0.1 < travel <= rate * (0.1 + 0.02) + rate**2 / (2 * 8.0)
    assert reading.velocity[0] == 0.0
    assert not reading.ok and "drive watchdog" in reading.message
    assert backend.counters() == {"drive_watchdog_stops": 1}
    backend.command(np.r_[rate, np.zeros(5)], t_last + gap_s)  # a fresh command moves it again
    assert backend.read(t_last + gap_s + 0.05).ok


def test_the_stop_does_not_depend_on_how_long_the_gap_was():
    ends = []
    for gap_s in (1.0, 5.0):
        backend, t_last = commanded_backend(0.5)
        ends.append(backend.read(t_last + gap_s).position)
    np.testing.assert_allclose(ends[0], ends[1], atol=1e-12)


def test_regular_commands_are_obeyed_as_before():
    """Commands every 10 ms never reach a 0.1 s watchdog: same path as the bare plant."""
    backend, t_last = commanded_backend(0.5)
    plant = SimJoints(PUMA, Q0, SimJointSettings(lag_tau=0.02, accel_max=8.0))
    for _ in range(round(t_last / 0.002)):
        plant.step(np.r_[0.5, np.zeros(5)], 0.002)
    np.testing.assert_allclose(backend.read(t_last).position, plant.q_reported, atol=1e-9)
    assert backend.counters() == {"drive_watchdog_stops": 0}
    with pytest.raises(UserError, match="drive_watchdog"):  # the module's declaration says so
        ModuleHarness(WolverineJnts, {"drive_watchdog": 0.0})


def test_a_rate_too_slow_for_the_drive_watchdog_is_a_graph_error():
    from umbra.modules.arm.wolverine_jnts import WolverineJnts

    params = WolverineJnts.Params(drive_watchdog=0.1)
    assert params.rate_problem(100.0) == ""
    assert "at least twice per watchdog time (20 Hz)" in params.rate_problem(10.0)
    assert WolverineJnts.Params(drive_watchdog=0.5).rate_problem(10.0) == ""
