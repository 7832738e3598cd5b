"""SONY in a graph run by the scheduler on the real clock, with the simulated camera on a pty."""

from __future__ import annotations

from pathlib import Path

from umbra.connectors import Input, Module
from umbra.connectors.messages import ZoomState
from umbra.modules.calib.visca.sony import Sony
from umbra.modules.generic.constant import Constant
from umbra.runtime.graph.check import check_text
from umbra.runtime.registry import Registry
from umbra.runtime.scheduler import Scheduler, SchedulerOptions


class ZoomProbe(Module):
    """Keeps every ZoomState it receives."""

    zoom = Input(ZoomState, trigger=True)

    def start(self) -> None:
        self.seen: list[ZoomState] = []

    def step(self, now: float) -> None:
        sample = self.zoom.get(now)
        if sample is not None:
            self.seen.append(sample)


GRAPH = """graph: zoom
clock: real
modules:
  operator: {type: Constant, rate: 20, params: {value: 0.5}}
  sony: {type: SONY, rate: 50, params: {port: sim, poll_rate_hz: 20, sim_full_range_s: 0.6}}
  probe: {type: ZoomProbe}
connections:
  - operator.output -> sony.zoom_command
  - sony.zoom -> probe.zoom
"""


def test_operator_zoom_reaches_the_camera_and_zoom_state_flows(tmp_path: Path) -> None:
    registry = Registry()
    for cls in (Constant, Sony, ZoomProbe):
        registry.add(cls)
    plan = check_text(GRAPH, "zoom.yaml", registry)
    scheduler = Scheduler(plan, SchedulerOptions(clock="real", duration=2.0, output_dir=tmp_path))
    result = scheduler.run()
    assert result.exit_code == 0, result.reason
    seen: list[ZoomState] = scheduler.modules["probe"].seen  # type: ignore[attr-defined]
    assert seen, "SONY published nothing"
    final = seen[-1]
    assert final.status == "ok" and final.zoom == 0.5 and final.raw == 0x2000
    assert not final.moving
    assert any(s.moving for s in seen)
    stamps = [s.stamp for s in seen if s.raw >= 0]
    assert stamps == sorted(stamps)  # stamped when each position arrived, in order
    sony_stats = next(m for m in result.modules if m.name == "sony")
    assert sony_stats.extra.get("zoom_completions") == 1
