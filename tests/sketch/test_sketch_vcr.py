"""The VCR path-parameter player: continuity at every transition, jerk-limited pause, retrace."""

from __future__ import annotations

import numpy as np
import pytest

from umbra.modules.trajectory.joint_path import JointPath
from umbra.modules.trajectory.vcr import Vcr, VcrError, VcrLimits

DT = 0.002
LIMITS = VcrLimits.for_stop_time(rate=0.5, stop_time_s=0.25)


def _run(vcr: Vcr, seconds: float, log: list) -> None:
    for _ in range(round(seconds / DT)):
        st = vcr.step(DT)
        log.append((st.s, st.s_dot, st.s_ddot, st.mode))


def _max_jumps(log: list) -> tuple[float, float, float]:
    arr = np.array([row[:3] for row in log])
    d = np.abs(np.diff(arr, axis=0))
    return float(d[:, 0].max()), float(d[:, 1].max()), float(d[:, 2].max())


def test_play_pause_back_speed_resume_without_jumps():
    vcr = Vcr(2.0, LIMITS)
    log: list = []
    vcr.command("play")
    _run(vcr, 1.0, log)
    assert log[-1][1] == pytest.approx(0.5, abs=1e-6)  # cruising at full rate
    vcr.command("speed", speed=0.3)
    _run(vcr, 0.5, log)
    assert log[-1][1] == pytest.approx(0.15, abs=1e-6)
    vcr.command("speed", speed=1.0)
    _run(vcr, 0.4, log)
    vcr.command("pause")
    t_pause = len(log)
    _run(vcr, 0.5, log)
    still = next(i for i in range(t_pause, len(log)) if log[i][3] == "paused")
    assert (still - t_pause) * DT <= 0.3
    vcr.command("back")
    _run(vcr, 0.6, log)
    assert log[-1][1] < -0.49
    vcr.command("play")  # reverse while moving backwards: smooth turn-around
    _run(vcr, 8.0, log)
    assert log[-1][3] == "done" and log[-1][0] == pytest.approx(2.0, abs=1e-9)
    ds, dv, da = _max_jumps(log)
    # per 2 ms step: position moves at most rate*dt, velocity at most a_max*dt, acc j_max*dt
    assert ds <= 0.5 * DT + 1e-9
    assert dv <= LIMITS.max_accel * DT * 1.001
    assert da <= LIMITS.max_jerk * DT * 1.001
    jerk = np.abs(np.diff([row[2] for row in log])) / DT
    assert jerk.max() <= LIMITS.max_jerk * 1.001


def test_halt_is_smooth_and_needs_a_new_play():
    vcr = Vcr(2.0, LIMITS)
    log: list = []
    vcr.command("play")
    _run(vcr, 1.0, log)
    vcr.halt("console lost")
    _run(vcr, 0.4, log)
    assert log[-1][3] == "halted" and vcr.state.reason == "console lost"
    s_halt = log[-1][0]
    _run(vcr, 0.5, log)
    assert log[-1][0] == s_halt  # stays on the path
    vcr.halt("guard stop", freeze=True)
    assert vcr.state.s_dot == 0.0
    vcr.command("resume")
    _run(vcr, 0.2, log)
    assert log[-1][0] > s_halt and vcr.state.reason == ""
    _, dv, _ = _max_jumps(log)
    assert dv <= LIMITS.max_accel * DT * 1.001


def test_stop_points_pause_the_player_for_gripper_events():
    vcr = Vcr(2.0, LIMITS, stops=[1.2])
    log: list = []
    vcr.command("play")
    _run(vcr, 4.0, log)
    assert vcr.state.mode == "at_stop" and vcr.state.s == pytest.approx(1.2, abs=1e-9)
    vcr.command("play")
    _run(vcr, 3.0, log)
    assert vcr.state.mode == "done"


def test_seek_and_bad_commands():
    vcr = Vcr(2.0, LIMITS)
    vcr.command("seek", s=0.7)
    log: list = []
    _run(vcr, 3.0, log)
    assert vcr.state.mode == "paused" and vcr.state.s == pytest.approx(0.7, abs=1e-9)
    with pytest.raises(VcrError, match=r"expected a speed within 0\.1 \.\. 1, got 1\.5"):
        vcr.command("speed", speed=1.5)
    with pytest.raises(VcrError, match="unknown VCR action 'rewind'"):
        vcr.command("rewind")
    with pytest.raises(VcrError, match=r"expected a seek target within 0 \.\. 2"):
        vcr.command("seek", s=-1)


def test_back_up_retraces_the_joint_path():
    s = np.linspace(0, 2.0, 9)
    joints = np.column_stack([np.sin(s), 0.5 * s**2, np.cos(2 * s)])
    path = JointPath(s, joints)
    vcr = Vcr(path.length, LIMITS)
    vcr.command("play")
    forward = []
    for i in range(1700):
        if i == 1500:
            vcr.command("pause")
        forward.append(path.q(vcr.step(DT).s))
    assert vcr.state.mode == "paused"
    vcr.command("back")
    backward = [path.q(vcr.step(DT).s) for _ in range(1700)]
    forward_arr, backward_arr = np.array(forward), np.array(backward)
    # every point visited backwards lies on the forward trace (dense in s)
    gaps = backward_arr[:, None, :] - forward_arr[None, :, :]
    dist = np.min(np.linalg.norm(gaps, axis=2), axis=1)
    assert dist.max() < 2e-3
    assert vcr.state.s == pytest.approx(0.0, abs=1e-9)
