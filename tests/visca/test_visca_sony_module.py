"""The SONY module through the public harness, on the simulated FCB camera (``port: sim``)."""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import pytest

from umbra.connectors.errors import UserError
from umbra.connectors.messages import Scalar, ZoomState
from umbra.modules.calib.visca import protocol as vp
from umbra.modules.calib.visca.sim_camera import SimFcbCamera
from umbra.modules.calib.visca.sony import Sony
from umbra.runtime.harness import ModuleHarness

FAST = {
    "poll_rate_hz": 20.0,
    "reply_timeout_s": 0.1,
    "retries": 1,
    "retry_backoff_s": 0.1,
    "sim_full_range_s": 1.0,
}


def step_until(
    h: ModuleHarness, done: Callable[[ZoomState], bool], timeout_s: float, dt: float = 0.01
) -> ZoomState | None:
    """Step the module (sim clock ``dt`` per step, ~dt of real time) until ``done(latest)``."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        h.step(dt)
        latest = h.output("zoom")
        if latest is not None and done(latest):
            return latest
        time.sleep(dt)
    return h.output("zoom")


def test_zoom_command_drives_the_simulated_camera_and_state_follows() -> None:
    with ModuleHarness(Sony, {"port": "sim", **FAST}) as h:
        first = step_until(h, lambda z: z.raw >= 0, 3.0)
        assert first is not None and first.status == "ok" and first.zoom == 0.0
        h.push("zoom_command", Scalar(value=0.5))
        final = step_until(h, lambda z: z.raw == 0x2000 and not z.moving, 4.0)
        assert final is not None
        assert final.zoom == 0.5 and final.raw == 0x2000 and final.status == "ok"
        states = h.outputs("zoom")
        assert any(s.moving and 0 < s.raw < 0x2000 for s in states)
        assert [s.seq for s in states] == list(range(1, len(states) + 1))
        summary = h.module.summary()
        assert summary["zoom_completions"] == 1 and summary["status"] == "ok"


def test_state_is_published_per_poll_not_per_step() -> None:
    with ModuleHarness(Sony, {"port": "sim", **FAST, "poll_rate_hz": 5.0}) as h:
        step_until(h, lambda z: z.raw >= 0, 3.0)
        before = len(h.outputs("zoom"))
        steps = 0
        deadline = time.monotonic() + 0.5
        while time.monotonic() < deadline:
            h.step(0.001)
            steps += 1
            time.sleep(0.001)
        published = len(h.outputs("zoom")) - before
        assert steps > 50
        assert published <= h.module.summary()["polls"]
        assert published < steps / 5


def test_new_commands_replace_old_ones_and_are_clamped() -> None:
    with ModuleHarness(Sony, {"port": "sim", **FAST}) as h:
        h.push("zoom_command", Scalar(value=0.9))
        h.step(0.01)
        h.push("zoom_command", Scalar(value=-2.0))
        final = step_until(h, lambda z: z.raw == 0 and not z.moving and z.status == "ok", 4.0)
        assert final is not None and final.zoom == 0.0 and final.status == "ok"


def test_a_nan_command_is_ignored_and_counted() -> None:
    with ModuleHarness(Sony, {"port": "sim", **FAST}) as h:
        h.push("zoom_command", Scalar(value=math.nan))
        h.step(0.01)
        assert h.module.summary()["ignored_commands"] == 1
        assert h.module.summary()["zoom_commands"] == 0


@pytest.mark.parametrize(
    ("fault", "prefix"),
    [("silent", "no_reply: "), ("garble", "garbled: "), ("error", "camera_error: ")],
)
def test_a_misbehaving_camera_is_reported_in_the_state(fault: str, prefix: str) -> None:
    params = {"port": "sim", **FAST, "sim_fault": fault, "start_timeout_s": 0.3}
    with ModuleHarness(Sony, params) as h:
        h.push("zoom_command", Scalar(value=0.5))
        state = step_until(h, lambda z: z.status.startswith(prefix), 3.0)
        assert state is not None and state.status.startswith(prefix), state
        if fault != "error":  # an error reply still answers; the others never gave a position
            assert math.isnan(state.zoom) and state.raw == -1


def test_module_talks_to_an_external_camera_on_its_pty() -> None:
    with SimFcbCamera(full_range_s=1.0) as camera:
        params = {**FAST, "port": camera.path}
        with ModuleHarness(Sony, params) as h:
            h.push("zoom_command", Scalar(value=0.25))
            final = step_until(h, lambda z: z.raw == 0x1000 and not z.moving, 4.0)
            assert final is not None and final.raw == 0x1000
            assert camera.position_raw() == vp.zoom_normalized_to_raw(0.25)


def test_a_port_that_cannot_be_opened_stops_start_with_a_user_error() -> None:
    h = ModuleHarness(Sony, {"port": "/nonexistent/ttyUSB7"})
    with pytest.raises(UserError, match=r"cannot open VISCA serial port '/nonexistent/ttyUSB7'"):
        h.start()
    h.module.stop()


@pytest.mark.parametrize(
    "params",
    [{"address": 0}, {"address": 8}, {"poll_rate_hz": 0}, {"baudrate": 4800}, {"retries": -1}],
)
def test_bad_parameters_are_user_errors(params: dict) -> None:
    with pytest.raises(UserError, match="bad parameters for SONY"):
        ModuleHarness(Sony, params)


def test_hold_tele_zooms_while_held_and_stops_when_released() -> None:
    with ModuleHarness(Sony, {"port": "sim", **FAST}) as h:
        step_until(h, lambda z: z.raw >= 0, 3.0)
        held: list[int] = []
        for _ in range(15):  # the rocker held (fastest) for ~0.3 s: a sample every step
            h.push("zoom_hold", Scalar(value=1.0))
            h.step(0.02)
            time.sleep(0.02)
        h.push("zoom_hold", Scalar(value=0.0))  # released
        stopped = step_until(h, lambda z: z.raw > 0 and not z.moving, 3.0)
        assert stopped is not None and 0 < stopped.raw < 0x4000, stopped
        held.append(stopped.raw)
        time.sleep(0.3)
        after = step_until(h, lambda z: False, 0.2)
        assert after is not None and after.raw == held[0]  # it stays where it stopped
        summary = h.module.summary()
        assert summary["zoom_moves"] == 2 and summary["deadman_stops"] == 0  # tele once, stop


def test_hold_wide_stops_by_itself_when_its_samples_stop_coming() -> None:
    params = {"port": "sim", **FAST, "hold_timeout_s": 0.2}
    with ModuleHarness(Sony, params) as h:
        h.push("zoom_command", Scalar(value=1.0))
        step_until(h, lambda z: z.raw == 0x4000 and not z.moving, 4.0)
        h.push("zoom_hold", Scalar(value=-0.5))  # one sample, then the operator's link dies
        h.step(0.01)
        for _ in range(30):  # 0.3 s of graph time without a hold sample: dead-man stop
            h.step(0.01)
            time.sleep(0.01)
        assert h.module.summary()["deadman_stops"] == 1
        stopped = step_until(h, lambda z: not z.moving and z.raw < 0x4000, 3.0)
        assert stopped is not None and 0 < stopped.raw < 0x4000
        time.sleep(0.3)
        assert step_until(h, lambda z: False, 0.1).raw == stopped.raw


@pytest.mark.parametrize(
    ("value", "move"),
    [(1.0, ("tele", 7)), (0.125, ("tele", 0)), (-0.5, ("wide", 3)), (-7.0, ("wide", 7))],
)
def test_hold_values_map_to_direction_and_speed(value: float, move: tuple[str, int]) -> None:
    from umbra.modules.calib.visca.sony import hold_move

    direction, speed = hold_move(value)  # type: ignore[misc]
    assert (direction.value, speed) == move
    assert hold_move(0.0) is None
