"""SONY stops the zoom it started when its run ends, on every end path: the harness's stop, a run
that reaches its duration, and a run that fails in another module. The simulated FCB camera runs
on its own real pty and outlives the module, so what the camera does after the end is seen."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
import serial

from tests.poll import wait_for
from tests.visca.raw_wire import position
from umbra.connectors import Module, Parameters, param
from umbra.connectors.messages import Scalar, ZoomState
from umbra.modules.calib.visca.sim_camera import SimFcbCamera
from umbra.modules.calib.visca.sony import Sony
from umbra.modules.generic.constant import Constant
from umbra.runtime.graph.check import check_text
from umbra.runtime.harness import ModuleHarness
from umbra.runtime.registry import Registry
from umbra.runtime.scheduler import Scheduler, SchedulerOptions

FAST = {"poll_rate_hz": 20.0, "reply_timeout_s": 0.1, "retries": 1, "retry_backoff_s": 0.1}
FULL_RANGE_S = 2.4
"""Simulated zoom direct travel, wide to tele [s]; the slowest hold speed takes 8 times longer."""


def assert_lens_stays(camera: SimFcbCamera, watch_s: float = 0.3) -> int:
    """The lens is at rest and its reported position does not change over ``watch_s`` [s] of
    position inquiries on the pty (a measurement window, not a wait); returns the position."""
    assert not camera.moving(), f"still zooming toward {camera.target_raw():#06x}"
    assert camera.target_raw() == camera.position_raw()
    with serial.Serial(camera.path, 9600, timeout=2.0) as port:
        first = position(port)
        seen = {first}
        deadline = time.monotonic() + watch_s
        while time.monotonic() < deadline:
            seen.add(position(port))
    assert seen == {first}, sorted(seen)
    return first


def hold_until_moving(h: ModuleHarness, camera: SimFcbCamera, value: float) -> None:
    """Send hold samples (the rocker held) until the camera's zoom has left raw 0."""

    def hold() -> None:
        h.push("zoom_hold", Scalar(value=value))
        h.step(0.02)

    wait_for(lambda: camera.position_raw() >= 0x200, 5.0, "the zoom off raw 0", 0.02, step=hold)
    assert camera.moving()


def test_a_held_zoom_is_stopped_when_the_module_stops() -> None:
    with SimFcbCamera(full_range_s=FULL_RANGE_S) as camera:
        with ModuleHarness(Sony, {**FAST, "port": camera.path, "hold_timeout_s": 5.0}) as h:
            hold_until_moving(h, camera, 0.1)  # slowest tele: 19 s to the tele end
        summary = h.module.summary()
        assert summary["end_zoom_stops"] == 1 and summary["end_zoom_stop_failures"] == 0
        stopped = assert_lens_stays(camera)
        assert 0x200 <= stopped < 0x4000


def test_a_zoom_direct_still_travelling_is_stopped_when_the_module_stops() -> None:
    with SimFcbCamera(full_range_s=FULL_RANGE_S) as camera:
        with ModuleHarness(Sony, {**FAST, "port": camera.path}) as h:
            h.push("zoom_command", Scalar(value=1.0))
            wait_for(
                lambda: camera.position_raw() >= 0x400,
                5.0,
                "the zoom past 0x400",
                0.02,
                step=lambda: h.step(0.02),
            )
            assert camera.moving()
        assert h.module.summary()["end_zoom_stops"] == 1
        assert 0x400 <= assert_lens_stays(camera) < 0x4000


def test_no_stop_is_sent_when_no_zoom_runs() -> None:
    with SimFcbCamera(full_range_s=0.5) as camera:
        with ModuleHarness(Sony, {**FAST, "port": camera.path}) as h:
            h.push("zoom_command", Scalar(value=0.5))

            def stepped() -> ZoomState | None:
                h.step(0.02)
                return h.output("zoom")

            wait_for(
                stepped,
                5.0,
                "the zoom at rest at 0x2000",
                0.02,
                ok=lambda s: s.raw == 0x2000 and not s.moving,
            )
            commands = camera.counters.commands
        assert h.module.summary()["end_zoom_stops"] == 0
        assert camera.counters.commands == commands  # nothing sent at the end
        assert assert_lens_stays(camera) == 0x2000


class FailAfter(Module):
    """Fails its step once ``after_s`` [s] of graph time have passed (another module's bug)."""

    class Params(Parameters):
        after_s: float = param(0.5, "when to fail", unit="s")

    def start(self) -> None:
        self._t0: float | None = None

    def step(self, now: float) -> None:
        self._t0 = now if self._t0 is None else self._t0
        if now - self._t0 >= self.params.after_s:
            raise RuntimeError("a module failed")


GRAPH = """graph: zoom_end
clock: real
modules:
  rocker: {{type: Constant, rate: 20, params: {{value: 0.1}}}}
  sony: {{type: SONY, rate: 50, params: {{port: {port}, poll_rate_hz: 20}}}}
  other: {{type: FailAfter, rate: 20, params: {{after_s: {fail_after_s}}}}}
connections:
  - rocker.output -> sony.zoom_hold
"""


@pytest.mark.parametrize(
    ("fail_after_s", "code"), [(0.8, 1), (30.0, 0)], ids=["run-fails", "run-ends"]
)
def test_a_run_that_ends_while_zooming_leaves_the_camera_still(
    tmp_path: Path, fail_after_s: float, code: int
) -> None:
    """The rocker holds tele for the whole run; the run ends by another module's failure
    (exit 1) or by its duration (exit 0): either way the camera stops with the run."""
    registry = Registry()
    for cls in (Constant, Sony, FailAfter):
        registry.add(cls)
    with SimFcbCamera(full_range_s=FULL_RANGE_S) as camera:
        text = GRAPH.format(port=camera.path, fail_after_s=fail_after_s)
        plan = check_text(text, "zoom_end.yaml", registry)
        options = SchedulerOptions(clock="real", duration=1.0, output_dir=tmp_path)
        result = Scheduler(plan, options).run()
        assert result.exit_code == code, result.reason
        sony = next(m for m in result.modules if m.name == "sony")
        assert sony.extra["zoom_moves"] == 1 and sony.extra["end_zoom_stops"] == 1
        assert 0 < assert_lens_stays(camera) < 0x4000
