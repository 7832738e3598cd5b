"""The scheduler: data order, triggers, delayed connections, clocks, failures, signals."""

from __future__ import annotations

import json
import os
import signal
import time
from pathlib import Path

import numpy as np
import pytest

from tests.poll import wait_for
from tests.recorded import messages_on_disk
from tests.runtime.fixtures import StopLog, make_registry, start_recording_run
from umbra.connectors import Input, Module, Output, Parameters, param
from umbra.connectors.messages import Scalar
from umbra.modules.generic.recording import read_recording
from umbra.runtime.graph.check import check_text
from umbra.runtime.run import run_process
from umbra.runtime.scheduler import Scheduler, SchedulerOptions


class Probe(Module):
    """Records (now, value, seq) of every sample it sees."""

    value = Input(Scalar, trigger=True)

    def start(self) -> None:
        self.seen: list[tuple[float, float, int]] = []

    def step(self, now: float) -> None:
        s = self.value.get(now)
        if s is not None:
            self.seen.append((now, s.value, s.seq))


class Accumulate(Module):
    """Sends its input + 1 every period (input optional)."""

    value = Input(Scalar, required=False)
    out = Output(Scalar)

    def step(self, now: float) -> None:
        s = self.value.get(now)
        self.out.send(Scalar(value=(s.value if s is not None else 0.0) + 1.0))


class Noisy(Module):
    """Sends a random number each period (from the context's seeded generator)."""

    class Params(Parameters):
        scale: float = param(1.0, "std")

    out = Output(Scalar)

    def step(self, now: float) -> None:
        self.out.send(Scalar(value=float(self.context.rng.normal(0, self.params.scale))))


def registry():
    reg = make_registry()
    for cls in (Probe, Accumulate, Noisy):
        reg.add(cls)
    return reg


def plan_of(text: str):
    return check_text(text, "t.yaml", registry())


def test_sample_crosses_a_chain_in_one_tick(tmp_path: Path) -> None:
    plan = plan_of("""graph: t
modules:
  probe: {type: Probe}
  g2: {type: Gain, params: {gain: 10}}
  g1: {type: Gain, params: {gain: 2}}
  src: {type: Counter, rate: 100}
connections:
  - g2.output -> probe.value
  - src.count -> g1.input
  - g1.output -> g2.input
""")
    assert plan.order == ["src", "g1", "g2", "probe"]
    sched = Scheduler(plan, SchedulerOptions(duration=0.1, output_dir=tmp_path))
    result = sched.run()
    assert result.exit_code == 0
    seen = sched.modules["probe"].seen
    assert len(seen) == 10
    for k, (now, value, _seq) in enumerate(seen):
        assert now == pytest.approx(k * 0.01)
        assert value == 20.0 * k  # counter value k, same tick


def test_delayed_connection_reads_previous_tick(tmp_path: Path) -> None:
    plan = plan_of("""graph: t
modules:
  a: {type: Accumulate, rate: 10}
  b: {type: Gain, params: {gain: 1}}
  probe: {type: Probe}
connections:
  - a.out -> b.input
  - b.output ~> a.value
  - a.out -> probe.value
""")
    sched = Scheduler(plan, SchedulerOptions(duration=0.5, output_dir=tmp_path))
    sched.run()
    values = [v for _, v, _ in sched.modules["probe"].seen]
    assert values == [1.0, 2.0, 3.0, 4.0, 5.0]


def test_rates_interleave(tmp_path: Path) -> None:
    plan = plan_of("""graph: t
modules:
  fast: {type: Counter, rate: 100}
  slow: {type: Counter, rate: 7}
  pf: {type: Probe}
  ps: {type: Probe}
connections: [fast.count -> pf.value, slow.count -> ps.value]
""")
    sched = Scheduler(plan, SchedulerOptions(duration=1.0, output_dir=tmp_path))
    sched.run()
    assert len(sched.modules["pf"].seen) == 100
    assert len(sched.modules["ps"].seen) == 7
    times = [t for t, _, _ in sched.modules["ps"].seen]
    assert np.allclose(np.diff(times), 1 / 7)


GRAPH_NOISE = """graph: t
seed: {seed}
modules:
  n: {{type: Noisy, rate: 50}}
  rec: {{type: Recorder, params: {{channels: [x]}}}}
connections: [n.out -> rec.x]
"""


def _noise(tmp_path: Path, seed: int, name: str) -> list[float]:
    out = tmp_path / name
    run_process(
        plan_of(GRAPH_NOISE.format(seed=seed)), SchedulerOptions(duration=1.0, output_dir=out)
    )
    return [m.value for _, m in read_recording(out / "recording.mcap")]


def test_sim_clock_is_deterministic_for_a_seed(tmp_path: Path) -> None:
    a, b, c = _noise(tmp_path, 3, "a"), _noise(tmp_path, 3, "b"), _noise(tmp_path, 4, "c")
    assert len(a) == 50
    assert a == b
    assert a != c


def test_real_clock_paces_to_wall_time(tmp_path: Path) -> None:
    plan = plan_of("graph: t\nmodules:\n  c: {type: Counter, rate: 100}\n")
    t0 = time.monotonic()
    result = Scheduler(
        plan, SchedulerOptions(clock="real", duration=0.3, output_dir=tmp_path)
    ).run()
    elapsed = time.monotonic() - t0
    assert elapsed >= 0.29  # it waited for the wall clock instead of racing ahead
    assert 20 <= result.modules[0].calls <= 31
    assert result.lateness_s.size == result.ticks


def test_module_failure_stops_cleanly_naming_module_and_tick(tmp_path: Path) -> None:
    StopLog.stopped.clear()
    plan = plan_of("""graph: t
modules:
  first: {type: StopLog, rate: 10}
  bad: {type: Boom, rate: 10, params: {at: 3}}
  last: {type: StopLog, rate: 10}
""")
    result = run_process(plan, SchedulerOptions(duration=5, output_dir=tmp_path))
    assert result.exit_code == 1
    assert "module `bad` (Boom) raised in step at tick 3" in result.reason
    assert "sensor on fire" in result.reason
    assert sorted(StopLog.stopped) == ["first", "last"]
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["exit_code"] == 1 and summary["modules"][1]["calls"] == 2


def test_max_age_violations_are_counted_and_not_delivered(tmp_path: Path) -> None:
    from tests.runtime.fixtures import Fresh
    from umbra.runtime.harness import ModuleHarness

    with ModuleHarness(Fresh) as h:
        h.push("value", Scalar(value=1.0))
        h.step(0.01)
        assert h.module.value.get(h.now) is not None
        h.step(0.1)
        assert h.module.value.get(h.now) is None
        assert h.module.value.violations == 1


def test_sigint_stops_with_130_and_writes_summary(tmp_path: Path) -> None:
    proc, out = start_recording_run(tmp_path)
    wait_for((out / "recording.mcap").exists, 30, "the recording file", 0.05)
    wait_for(
        lambda: sum(messages_on_disk(out / "recording.mcap").values()) > 5,
        30,
        "6 samples recorded",
        0.1,
    )
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 130, err
    assert "Traceback" not in err
    assert "interrupted by SIGINT" in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["exit_code"] == 130
    assert len(list(read_recording(out / "recording.mcap"))) > 5


@pytest.mark.skipif(not hasattr(os, "fork"), reason="needs POSIX")
def test_request_stop_ends_the_run(tmp_path: Path) -> None:
    plan = plan_of("graph: t\nmodules:\n  c: {type: Counter, rate: 10, params: {stop_after: 4}}\n")
    result = run_process(plan, SchedulerOptions(duration=100, output_dir=tmp_path))
    assert result.exit_code == 0 and result.reason == "`c` sent 4 values"
    assert result.modules[0].calls == 4
