"""The grab's stage machine, driven by the simulated camera and a scripted snake."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from tests.servo.servo_scene import INTRINSICS, camera_above, features_seen, move
from umbra.connectors.states import ServoReason
from umbra.modules.servo.goal import goal_from_standoff
from umbra.modules.servo.stages import (
    ABORTED,
    ACQUIRE,
    APPROACH,
    ASSIST,
    DONE,
    FINAL_GRAB,
    Observation,
    ServoStages,
    StageSettings,
)

DT = 0.02
GOAL = goal_from_standoff(0.2, INTRINSICS)
SETTINGS = StageSettings(acquire_frames=3, settle_frames=4, grab_distance=0.05, grab_speed=0.025)


def healthy(T, now):
    return Observation(features_seen(T), healthy=True, stamp=now)


def run_grab(machine, T, now=0.0, fail_at=None, max_steps=3000):
    """Tick the machine with a camera that follows its twist; returns (T, now, outputs)."""
    outputs = []
    for _ in range(max_steps):
        failing = fail_at is not None and fail_at(machine, now)
        observation = (
            Observation(None, healthy=False, stamp=now, reason="point outside outer rectangle")
            if failing
            else healthy(T, now)
        )
        out = machine.step(now, observation)
        outputs.append(out)
        T = move(T, out.camera_twist, DT)
        now += DT
        if out.stage in (DONE, ASSIST, ABORTED):
            break
    return T, now, outputs


def test_a_full_grab_goes_through_every_stage_in_order():
    machine = ServoStages(GOAL, settings=SETTINGS)
    T_start = camera_above(0.04, -0.03, 0.4, 25.0)
    T, _, outputs = run_grab(machine, T_start)
    stages = [o.stage for o in outputs]
    first = {s: stages.index(s) for s in (ACQUIRE, APPROACH, FINAL_GRAB, DONE)}
    assert first[ACQUIRE] < first[APPROACH] < first[FINAL_GRAB] < first[DONE]
    # Acquisition holds still for the N healthy frames.
    assert stages[: SETTINGS.acquire_frames] == [ACQUIRE] * SETTINGS.acquire_frames
    assert all(not np.any(o.camera_twist) for o in outputs if o.stage == ACQUIRE)
    # The gripper is opened at the start and closed once, during the final grab.
    assert outputs[0].gripper == "open"
    closes = [o for o in outputs if o.gripper == "close"]
    assert len(closes) == 1 and closes[0].stage == FINAL_GRAB
    # Final grab: straight along the optical axis, by the set distance (standoff 0.2 -> 0.15).
    advancing = [o.camera_twist for o in outputs if o.message == "advancing"]
    # Full speed, then the last step cut to what is left (no overshoot by a step's travel).
    assert advancing and all(np.allclose(t, [0, 0, 0.025, 0, 0, 0]) for t in advancing[:-1])
    assert 0 < advancing[-1][2] < 0.025 and np.allclose(advancing[-1][[0, 1, 3, 4, 5]], 0)
    assert T[2, 3] == pytest.approx(0.2 - 0.05, abs=1e-3)
    np.testing.assert_allclose(T[:2, 3], 0.0, atol=3e-3)


def test_the_final_grab_takes_along_the_depth_error_left_when_the_approach_settled():
    # The camera holds still 0.8 mm short of the standoff: within the 1 mm tolerance, so the
    # approach settles there; the open-loop advance must cover the 0.8 mm too.
    machine = ServoStages(GOAL, settings=SETTINGS)
    T = camera_above(0.0, 0.0, 0.2008, 0.0)
    now, advanced = 0.0, 0.0
    for _ in range(400):
        out = machine.step(now, healthy(T, now))
        if out.stage == FINAL_GRAB:
            advanced += out.camera_twist[2] * DT
        elif machine.stage == APPROACH:
            T = camera_above(0.0, 0.0, 0.2008, 0.0)  # the arm does not move in the approach
        now += DT
        if out.stage == DONE:
            break
    assert out.stage == DONE
    assert advanced == pytest.approx(0.05 + 0.0008, abs=5e-5)


def test_snake_failure_stops_at_once_and_asks_the_operator():
    machine = ServoStages(GOAL, settings=SETTINGS)
    # Fail during the approach, while the camera is moving.
    fail = lambda m, now: m.stage == APPROACH and now > 1.0  # noqa: E731
    _, now, outputs = run_grab(machine, camera_above(0.04, -0.03, 0.4, 25.0), fail_at=fail)
    assert np.any(outputs[-2].camera_twist)  # it was moving the tick before
    last = outputs[-1]
    assert last.stage == ASSIST and last.assist
    assert not np.any(last.camera_twist)
    assert last.reason == "snake failure: point outside outer rectangle"
    # It stays stopped, even if the snake recovers, until the operator says so.
    T = camera_above(0.0, 0.0, 0.3, 0.0)
    assert machine.step(now + DT, healthy(T, now + DT)).stage == ASSIST
    machine.operator("resume")
    assert machine.stage == ACQUIRE
    out = machine.step(now + 2 * DT, healthy(T, now + 2 * DT))
    assert out.stage == ACQUIRE and not np.any(out.camera_twist)


def test_failure_during_the_final_grab_also_stops():
    machine = ServoStages(GOAL, settings=SETTINGS)
    fail = lambda m, now: m.stage == FINAL_GRAB  # noqa: E731
    _, _, outputs = run_grab(machine, camera_above(0.0, 0.0, 0.25, 5.0), fail_at=fail)
    assert outputs[-1].stage == ASSIST
    assert not np.any(outputs[-1].camera_twist)


def test_the_fingers_closing_over_the_patch_do_not_stop_a_grab_that_reached_its_grasp():
    """The snake fails (the fingers hide the patch) or loses its contour while the gripper
    closes: the grab still ends in done, not in an assistance request (its advance did)."""
    for blind in (
        Observation(None, healthy=False, stamp=0.0, reason="6 vertices inside the inner ellipse"),
        Observation(None, healthy=True, stamp=0.0),  # no contour at all
    ):
        machine = ServoStages(GOAL, settings=SETTINGS)
        closing = lambda m, now: m.stage == FINAL_GRAB and m._close_start is not None  # noqa: E731
        stages, now, T = [], 0.0, camera_above(0.0, 0.0, 0.25, 5.0)
        for _ in range(3000):
            seen = dataclasses.replace(blind, stamp=now) if closing(machine, now) else None
            out = machine.step(now, seen or healthy(T, now))
            stages.append(out.stage)
            T = move(T, out.camera_twist, DT)
            now += DT
            if out.stage in (DONE, ASSIST):
                break
        assert stages[-1] == DONE and ASSIST not in stages
        blind_ticks = round(SETTINGS.gripper_close_time / DT)
        assert stages[-blind_ticks - 1 : -1] == [FINAL_GRAB] * blind_ticks  # it was blind then


def test_acquisition_waits_for_a_contour_and_restarts_its_count():
    machine = ServoStages(GOAL, settings=StageSettings(acquire_frames=3, max_contour_age=0.1))
    T = camera_above(0.0, 0.0, 0.3, 0.0)
    out = machine.step(0.0, None)
    assert out.stage == ACQUIRE and out.message == "waiting: no contour from the snake"
    assert out.code == ServoReason.NO_CONTOUR
    machine.step(0.1, healthy(T, 0.1))
    machine.step(0.2, healthy(T, 0.2))
    out = machine.step(0.3, Observation(None, healthy=True, stamp=0.3))  # snake went idle
    assert out.stage == ACQUIRE and out.message == "waiting: snake has no contour"
    assert out.code == ServoReason.NOT_SEEDED
    machine.step(0.4, healthy(T, 0.4))
    machine.step(0.5, healthy(T, 0.5))
    assert machine.stage == ACQUIRE  # the count started again
    machine.step(0.6, healthy(T, 0.6))
    assert machine.stage == APPROACH


def test_stale_or_missing_contours_stop_the_approach():
    settings = StageSettings(acquire_frames=1, max_contour_age=0.1)
    T = camera_above(0.05, 0.0, 0.3, 0.0)
    for bad, reason, code in (
        (
            Observation(features_seen(T), healthy=True, stamp=0.8),
            "0.200 s old",
            ServoReason.CONTOUR_LATE,
        ),
        (None, "no contour from the snake", ServoReason.NO_CONTOUR),
    ):
        machine = ServoStages(GOAL, settings=settings)
        machine.step(0.9, healthy(T, 0.9))
        assert np.any(machine.step(0.95, healthy(T, 0.95)).camera_twist)
        out = machine.step(1.0, bad)
        assert out.stage == ASSIST and reason in out.reason and out.code == code
        assert not np.any(out.camera_twist)


def test_abort_from_any_stage_and_resume_starts_a_new_grab():
    machine = ServoStages(GOAL, settings=SETTINGS)
    T = camera_above(0.02, 0.0, 0.3, 0.0)
    for i in range(5):
        machine.step(i * DT, healthy(T, i * DT))
    assert machine.stage == APPROACH
    machine.operator("abort")
    out = machine.step(1.0, healthy(T, 1.0))
    assert out.stage == ABORTED and not np.any(out.camera_twist)
    assert out.reason == "aborted by the operator" and out.code == ServoReason.ABORTED
    machine.operator("resume")
    assert machine.step(1.1, healthy(T, 1.1)).gripper == "open"
    with pytest.raises(ValueError, match="resume"):
        machine.operator("jump")


def test_the_final_grab_counts_no_advance_while_the_guard_holds_the_arm():
    """Under overload the register zeroes stale commands mid-grab: the dead reckoning must not
    count what never moved, or the gripper closes short of the patch (10.7 mm short in a 4x
    overloaded trial before this rule)."""
    machine = ServoStages(GOAL, settings=SETTINGS)
    T = camera_above(0.0, 0.0, 0.2, 0.0)
    now, moved = 0.0, 0.0
    for step in range(800):
        held = machine.stage == FINAL_GRAB and step % 3 == 0  # the guard zeroes every third tick
        observation = dataclasses.replace(healthy(T, now), commands_pass=not held)
        out = machine.step(now, observation)
        if machine.stage in (FINAL_GRAB, DONE) and not held:
            moved += out.camera_twist[2] * DT  # what the guard let through moves the arm
        now += DT
        if out.stage == DONE:
            break
    assert out.stage == DONE
    assert moved == pytest.approx(0.05, abs=1e-3)  # the whole advance, however interrupted


def test_the_final_grab_measures_its_advance_on_the_guards_odometer():
    """With the guard's odometer (what REG_VEL let through), the grab advances the whole distance
    whatever the guard held back, and whenever its reports come."""
    machine = ServoStages(GOAL, settings=SETTINGS)
    T = camera_above(0.0, 0.0, 0.2, 0.0)
    rng = np.random.default_rng(3)
    now, travel, twist_z = 0.0, 0.0, 0.0
    for _ in range(2000):
        if machine.stage == FINAL_GRAB and rng.random() > 0.4:  # the guard passes 60 % of ticks
            travel += twist_z * DT
        observation = dataclasses.replace(healthy(T, now), guard_travel_z=travel)
        out = machine.step(now, observation)
        twist_z = out.camera_twist[2]
        now += DT
        if out.stage == DONE:
            break
    assert out.stage == DONE
    assert travel == pytest.approx(0.05, abs=0.025 * DT + 1e-9)  # within one tick's advance
