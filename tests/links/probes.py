"""Modules that watch links from the consumer's side, for the link tests.

They are registered in the test's child processes the way a third-party package registers its
modules: through an ``umbra.modules`` entry point (see ``conftest.plugin_env``).
"""

from __future__ import annotations

import math
import time

import numpy as np

from umbra.connectors import Input, Module, Output, Parameters, param
from umbra.connectors.messages import JointState, Scalar, Twist, Vector
from umbra.connectors.states import GuardState

#: Joint motion [rad] beyond which ArmWatch says the arm moved (far below a 0.1 mm step).
MOVED_RAD = 1e-6


class LinkWatch(Module):
    """A watchdog on one input: healthy while the producer is alive and the latest sample is at
    most ``timeout`` old. Counts firings and recoveries, and when each first happened [clock s]."""

    TYPE = "LinkWatch"

    class Params(Parameters):
        timeout: float = param(0.2, "largest accepted sample age", unit="s", gt=0)

    input = Input(Scalar, doc="the watched link")

    def start(self) -> None:
        self._healthy = False
        self.fired = 0
        self.revived = 0
        self.first_up = math.nan
        self.first_dead = math.nan  # first step that saw the producer gone (liveliness)
        self.last_dead = math.nan  # latest step at which the producer went from alive to gone
        self._was_alive = True
        self.first_fired = math.nan
        self.last_revived = math.nan
        self.seq_at_revival = -1

    def step(self, now: float) -> None:
        reg = self.input
        healthy = reg.value is not None and reg.link_alive and reg.age(now) <= self.params.timeout
        if reg.value is not None and not reg.link_alive and self._was_alive:
            self.last_dead = now
            if math.isnan(self.first_dead):
                self.first_dead = now
        self._was_alive = reg.link_alive or reg.value is None
        if healthy == self._healthy:
            return
        self._healthy = healthy
        if healthy:
            if math.isnan(self.first_up):
                self.first_up = now
                self.log.info("link up (seq %d)", reg.seq)
            else:
                self.revived += 1
                self.last_revived = now
                self.seq_at_revival = reg.seq
                self.log.info("link healthy again (seq %d)", reg.seq)
        else:
            self.fired += 1
            if math.isnan(self.first_fired):
                self.first_fired = now
            self.log.info(
                "watchdog fired: producer alive %s, age %.3f s", reg.link_alive, reg.age(now)
            )

    def summary(self) -> dict[str, object]:
        return {
            "fired": self.fired,
            "revived": self.revived,
            "first_up": self.first_up,
            "first_dead": self.first_dead,
            "last_dead": self.last_dead,
            "first_fired": self.first_fired,
            "last_revived": self.last_revived,
            "seq_at_revival": self.seq_at_revival,
            "last_seq": self.input.seq,
        }


class ProbeGuard(Module):
    """A safety guard: turns each scalar into a twist [value, 0, 0, 0, 0, 0] in ``camera``; the
    runtime zeroes its output when the run stops."""

    TYPE = "ProbeGuard"
    SAFETY_GUARD = True

    class Params(Parameters):
        tell_after: int = param(0, "twists sent before it says so once (0: never)", ge=0)

    value = Input(Scalar, trigger=True, doc="speed along x")
    twist = Output(Twist, frame="camera", doc="guarded twist")

    def start(self) -> None:
        self.sent = 0

    def step(self, now: float) -> None:
        sample = self.value.get(now)
        if sample is not None:
            self.twist.send(Twist(vector=np.array([sample.value, 0, 0, 0, 0, 0.0]), frame="camera"))
            self.sent += 1
            if self.sent == self.params.tell_after:
                self.log.info("guard: %d twists sent", self.sent)


class Boom(Module):
    """Fails in ``step`` once its input reaches ``at``."""

    TYPE = "Boom"

    class Params(Parameters):
        at: float = param(10.0, "value that makes it fail")

    value = Input(Scalar, trigger=True, doc="watched value")

    def step(self, now: float) -> None:
        sample = self.value.get(now)
        if sample is not None and sample.value >= self.params.at:
            raise RuntimeError(f"boom at {sample.value:g}")


class ProbeTwist(Module):
    """The genuine command of the attack tests: a constant twist ``vx`` [m/s] in ``camera``."""

    TYPE = "ProbeTwist"

    class Params(Parameters):
        vx: float = param(0.0, "speed along the camera's x axis", unit="m/s")
        origin_lag: float = param(
            0.0, "how old the sensor data behind each command is", unit="s", ge=0.0, le=10.0
        )

    twist = Output(Twist, frame="camera", doc="constant twist")

    def step(self, now: float) -> None:
        vector = np.array([self.params.vx, 0, 0, 0, 0, 0.0])
        lag = self.params.origin_lag
        self.twist.send(Twist(vector=vector, frame="camera", origin=now - lag if lag else 0.0))


class Ballast(Module):
    """A lossless stream of ``floats`` numbers a step (bytes on the wire, under the frame pool's
    threshold so they cross a link as they are): what fills a slow link and holds the rest of
    its traffic behind it in the socket."""

    TYPE = "Ballast"

    class Params(Parameters):
        floats: int = param(1500, "numbers a sample", ge=1, le=2000)

    load = Output(Vector, events=True, doc="ballast")

    def step(self, now: float) -> None:
        self.load.send(
            Vector(values=self.context.rng.random(self.params.floats))
        )  # no zeros: incompressible


class ArmWatch(Module):
    """Watches the servo side: how far the joints moved from where they started [rad] and when
    they first moved, the longest gap between two of its own steps [s, wall time], and the
    guard's verdicts. Times are ``time.monotonic()``, which every process of a host shares."""

    TYPE = "ArmWatch"

    joints = Input(JointState, doc="the arm's reported joints")
    guard = Input(GuardState, required=False, doc="the velocity register's state")

    def start(self) -> None:
        self.q0: np.ndarray | None = None
        self.moved = 0.0
        self.first_moved_at = math.nan  # when the joints first moved (time.monotonic)
        self.max_gap = 0.0
        self.max_gap_at = math.nan  # when it ended (time.monotonic)
        self.long_gaps: list[tuple[float, float]] = []  # (end [monotonic s], gap [s]) > 15 ms
        self._last_wall: float | None = None
        self.zeroed = 0  # times the guard went from passing to zero
        self.zeroed_at: list[float] = []  # when each happened (time.monotonic), first 100
        self._passing = False
        self._seen_status = -1

    def step(self, now: float) -> None:
        wall = time.monotonic()
        if self._last_wall is not None and self.q0 is not None:
            gap = wall - self._last_wall
            if gap > self.max_gap:
                self.max_gap, self.max_gap_at = gap, wall
            if gap > 0.015 and len(self.long_gaps) < 100:
                self.long_gaps.append((round(wall, 4), round(gap, 4)))
        self._last_wall = wall
        state = self.joints.get(now)
        if state is not None:
            q = np.asarray(state.position, dtype=float)
            if self.q0 is None:
                self.q0 = q.copy()
            self.moved = max(self.moved, float(np.max(np.abs(q - self.q0))))
            if self.moved > MOVED_RAD and math.isnan(self.first_moved_at):
                self.first_moved_at = round(wall, 4)
        status = self.guard.get(now)
        if status is not None and self.guard.seq != self._seen_status:
            self._seen_status = self.guard.seq
            passing = status.passing
            if self._passing and not passing:
                self.zeroed += 1
                if len(self.zeroed_at) < 100:
                    self.zeroed_at.append(round(time.monotonic(), 4))
                self.log.info("guard zeroed: %s", status.reason or status.message)
            elif passing and not self._passing:
                self.log.info("guard passing")
            self._passing = passing

    def summary(self) -> dict[str, object]:
        return {
            "moved_rad": self.moved,
            "first_moved_at": self.first_moved_at,
            "max_gap_s": self.max_gap,
            "max_gap_at": self.max_gap_at,
            "long_gaps": self.long_gaps,
            "zeroed": self.zeroed,
            "zeroed_at": self.zeroed_at,
        }
