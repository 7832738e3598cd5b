"""Origins: every sample carries the capture time of the oldest sensor data behind it.

Propagation through one module (fan-in, events, narrowing, measured outputs) is tested on the
harness; through graphs (chains, delayed loops) on the scheduler, sim clock; what ``umbra check``
derives from the same declarations at the end.
"""

from __future__ import annotations

import math
from pathlib import Path

import hypothesis.strategies as st
import numpy as np
import pytest
from hypothesis import given, settings

from umbra.connectors import Input, Module, Output, Parameters, param
from umbra.connectors.errors import CheckFailed
from umbra.connectors.messages import Scalar, Text
from umbra.runtime.graph.check import check_text
from umbra.runtime.graph.origin_age import bounded_inputs
from umbra.runtime.harness import ModuleHarness
from umbra.runtime.registry import Registry
from umbra.runtime.scheduler import Scheduler, SchedulerOptions


class Mix(Module):
    """Sums whatever of ``a`` and ``b`` it has; ``note`` is an event it reads every step."""

    a = Input(Scalar, trigger=True, required=False)
    b = Input(Scalar, required=False)
    note = Input(Text, required=False)
    out = Output(Scalar)
    only_a = Output(Scalar, origin_from=("a",))

    def step(self, now: float) -> None:
        total = 0.0
        for reg in (self.a, self.b):
            sample = reg.get(now)
            if sample is not None:
                total += sample.value
        self.note.get(now)
        self.out.send(Scalar(value=total))
        self.only_a.send(Scalar(value=total))


class Sensor(Module):
    """A measurement that reads a command (like a joint driver): still a new origin."""

    command = Input(Scalar, required=False)
    reading = Output(Scalar, measured=True)

    def step(self, now: float) -> None:
        command = self.command.get(now)
        self.reading.send(Scalar(value=0.0 if command is None else command.value))


class Relay(Module):
    """Passes what it reads on its rate (adds one period of age at worst)."""

    class Params(Parameters):
        max_origin_age: float = param(1.0, "bound on what it accepts", unit="s", gt=0)

    input = Input(Scalar, trigger=False, max_origin_age=0.25)
    output = Output(Scalar)

    def step(self, now: float) -> None:
        sample = self.input.get(now)
        if sample is not None:
            self.output.send(Scalar(value=sample.value))


class Pass(Module):
    """Passes what it reads, on its trigger."""

    input = Input(Scalar, trigger=True)
    output = Output(Scalar)

    def step(self, now: float) -> None:
        sample = self.input.get(now)
        if sample is not None:
            self.output.send(Scalar(value=sample.value))


class Probe(Module):
    """Keeps every origin age it sees [s] (class-level list: test bookkeeping)."""

    ages: list[float] = []  # noqa: RUF012
    input = Input(Scalar, trigger=True)

    def step(self, now: float) -> None:
        sample = self.input.get(now)
        if sample is not None:
            Probe.ages.append(now - sample.origin)


def _registry() -> Registry:
    reg = Registry()
    for cls in (Mix, Sensor, Relay, Pass, Probe):
        reg.add(cls)
    return reg


def test_an_output_takes_the_oldest_origin_of_what_the_step_read() -> None:
    with ModuleHarness(Mix) as h:
        h.step(1.0)
        h.push("a", Scalar(value=1.0, stamp=0.9, origin=0.4))
        h.push("b", Scalar(value=1.0, stamp=0.95, origin=0.7))
        sent = h.step(0.1)
        assert sent["out"][0].origin == 0.4  # fan-in: the oldest
        assert sent["out"][0].stamp == pytest.approx(1.1)  # its own stamp is the step's
        h.push("b", Scalar(value=1.0, stamp=1.15, origin=0.2))
        sent = h.step(0.1)
        assert sent["out"][0].origin == 0.2
        assert sent["only_a"][0].origin == 0.4  # narrowed to `a`: b's old data does not count


def test_an_old_event_dates_nothing_once_handled() -> None:
    """An operator's command from a minute ago must not make every later output a minute old;
    the step in which it arrives is dated by it."""
    with ModuleHarness(Mix) as h:
        h.module.note.events = True  # as the scheduler marks inputs fed by an events output
        h.step(60.0)
        h.push("note", Text(text="start", stamp=1.0, origin=1.0))
        h.push("a", Scalar(value=1.0, stamp=60.0, origin=59.99))
        assert h.step(0.01)["out"][0].origin == 1.0  # the step that handled the event
        h.push("a", Scalar(value=1.0, stamp=60.02, origin=60.0))
        assert h.step(0.01)["out"][0].origin == 60.0  # the event is old news now


def test_a_measured_output_starts_a_new_origin_whatever_its_module_read() -> None:
    with ModuleHarness(Sensor) as h:
        h.step(5.0)
        h.push("command", Scalar(value=0.1, stamp=5.0, origin=1.0))
        out = h.step(0.01)["reading"][0]
        assert out.origin == out.stamp == pytest.approx(5.01)


def test_a_narrowed_output_whose_inputs_have_nothing_cannot_be_dated() -> None:
    with ModuleHarness(Mix) as h:
        h.push("b", Scalar(value=1.0, origin=0.5))
        assert h.step(0.1)["only_a"][0].origin == -math.inf


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.floats(0.0, 100.0), st.floats(0.0, 100.0)), min_size=1, max_size=20))
def test_fan_in_origin_is_the_minimum_for_any_sequence(pairs: list[tuple[float, float]]) -> None:
    """Property: whatever origins arrive on two inputs, each output is dated by the oldest latest
    one, and never later than its own stamp."""
    with ModuleHarness(Mix) as h:
        h.step(200.0)
        for oa, ob in pairs:
            a = h.push("a", Scalar(value=0.0, stamp=h.now, origin=oa or 1e-9))
            b = h.push("b", Scalar(value=0.0, stamp=h.now, origin=ob or 1e-9))
            out = h.step(0.01)["out"][0]
            assert out.origin == min(a.origin, b.origin)
            assert out.origin <= out.stamp


GRAPH = """
graph: origins
clock: sim
modules:
  sensor: {{type: Sensor, rate: {sensor_hz}}}
  relay: {{type: Relay, rate: {relay_hz}}}
  pass: {{type: Pass}}
  probe: {{type: Probe}}
connections:
  - sensor.reading -> relay.input
  - relay.output -> pass.input
  - pass.output -> probe.input
  - pass.output ~> sensor.command    # a loop closed through the sensor
"""


def test_origins_advance_around_a_delayed_loop_through_a_measurement(tmp_path: Path) -> None:
    """The loop sensor -> relay -> pass ~> sensor: the sensor reads the loop's command, yet each
    reading is new data, so the age the probe sees stays within the rates' bound (10 Hz sensor:
    0.1 s; 50 Hz relay: 0.02 s) instead of growing with the run."""
    Probe.ages = []
    plan = check_text(GRAPH.format(sensor_hz=10, relay_hz=50), "g.yaml", _registry())
    Scheduler(plan, SchedulerOptions(duration=5.0, output_dir=tmp_path)).run()
    ages = np.asarray(Probe.ages)
    assert len(ages) > 200
    assert ages.max() <= 0.1 + 0.02 + 1e-9
    assert ages.min() >= 0.0
    early, late = ages[: len(ages) // 5], ages[-len(ages) // 5 :]
    assert late.max() == pytest.approx(early.max())  # no growth over the run
    (bounded,) = bounded_inputs(plan.modules, plan.connections)
    assert bounded.worst.age == pytest.approx(0.1)  # what check derives at relay.input
    assert ages.max() <= bounded.worst.age + 0.02 + 1e-9  # (the probe is one relay period on)


def test_check_refuses_a_bound_the_rates_cannot_meet() -> None:
    text = GRAPH.format(sensor_hz=3, relay_hz=50)  # 0.333 s at relay.input > its 0.25 s bound
    with pytest.raises(CheckFailed) as err:
        check_text(text, "g.yaml", _registry())
    message = str(err.value)
    assert "g.yaml:10:5: error: `relay.input` accepts commands made from sensor data up to " in (
        message
    )
    assert "0.25 s old (max_origin_age), but the graph's rates allow 0.333 s" in message
    assert "sensor.reading (measured) +333 ms" in message


def test_check_refuses_a_loop_that_would_freeze_origins() -> None:
    text = """
graph: frozen
modules:
  relay: {type: Relay, rate: 50}
  pass: {type: Pass}
connections:
  - relay.output -> pass.input
  - pass.output ~> relay.input
"""
    with pytest.raises(CheckFailed) as err:
        check_text(text, "f.yaml", _registry())
    assert "origins flow around the loop" in str(err.value)
    assert "no measured output" in str(err.value)
