"""Small module types used by the runtime tests (registered directly, not by entry points), and
a real-clock run of ``umbra`` to signal."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

from umbra.connectors import Input, Module, Output, Parameters, from_param, param
from umbra.connectors.messages import JointRates, JointState, Scalar, Twist
from umbra.runtime.registry import Registry


class TwistSink(Module):
    """Consumes a twist in the frame named by its parameter."""

    class Params(Parameters):
        frame: str = param("tool", "frame wanted")

    twist = Input(Twist, frame=from_param("frame"), trigger=True)


class Guard(Module):
    """A watchdog register (safety guard) passing tool-frame twists."""

    SAFETY_GUARD = True
    twist_in = Input(Twist, frame="tool", trigger=True)
    twist_out = Output(Twist, frame="tool")

    def step(self, now: float) -> None:
        sample = self.twist_in.get(now)
        if sample is not None:
            self.twist_out.send(sample)


class Kin(Module):
    """Tool twist + joint feedback -> joint rates for the joints named in parameters."""

    class Params(Parameters):
        joints: list[str] = param(["j1", "j2", "j3"], "joint names")

    twist = Input(Twist, frame="tool", trigger=True)
    joint_state = Input(JointState, joints=from_param("joints"), feedback=True, required=False)
    rates = Output(JointRates, joints=from_param("joints"))

    def step(self, now: float) -> None:
        sample = self.twist.get(now)
        if sample is not None:
            self.rates.send(JointRates(names=tuple(self.params.joints), rates=sample.vector[:3]))


class Driver(Module):
    """A joint driver whose rates input must be fed through a guard."""

    class Params(Parameters):
        joints: list[str] = param(["j1", "j2", "j3"], "joint names")

    rates = Input(JointRates, joints=from_param("joints"), requires_guard=True, trigger=True)
    state = Output(JointState, joints=from_param("joints"))

    def step(self, now: float) -> None:
        sample = self.rates.get(now)
        if sample is not None:
            self.state.send(JointState(names=sample.names, position=np.asarray(sample.rates)))


class ToolTwistSource(Module):
    """A vision-like source of tool-frame twists."""

    twist = Output(Twist, frame="tool")

    def step(self, now: float) -> None:
        self.twist.send(Twist(vector=np.ones(6), frame="tool"))


class Fresh(Module):
    """Accepts scalars at most 0.05 s old."""

    value = Input(Scalar, max_age=0.05, trigger=True)


class Boom(Module):
    """Raises on its third step."""

    class Params(Parameters):
        at: int = param(3, "step that raises", ge=1)

    def start(self) -> None:
        self.n = 0

    def step(self, now: float) -> None:
        self.n += 1
        if self.n == self.params.at:
            raise RuntimeError("sensor on fire")


class StopLog(Module):
    """Records that stop ran (in a list passed through the class)."""

    stopped: list[str] = []  # noqa: RUF012 - test-only bookkeeping

    def stop(self) -> None:
        StopLog.stopped.append(self.name)


def make_registry() -> Registry:
    """The entry-point registry plus the test types."""
    reg = Registry()
    for cls in (TwistSink, Guard, Kin, Driver, ToolTwistSource, Fresh, Boom, StopLog):
        reg.add(cls)
    return reg


def start_recording_run(tmp_path: Path) -> tuple[subprocess.Popen[str], Path]:
    """``umbra run`` of a real-clock graph that records a counter until it is stopped, in
    ``tmp_path`` (stderr piped as text, stdout dropped); the process and its output folder."""
    graph = tmp_path / "g.yaml"
    graph.write_text(
        "graph: g\nclock: real\nmodules:\n  c: {type: Counter, rate: 50}\n"
        "  rec: {type: Recorder, params: {channels: [x]}}\n"
        "connections: [c.count -> rec.x]\n"
    )
    out = tmp_path / "out"
    proc = subprocess.Popen(
        [sys.executable, "-m", "umbra.runtime.cli.main", "run", str(graph), "--out", str(out)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    return proc, out
