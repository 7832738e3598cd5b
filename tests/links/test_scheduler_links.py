"""What the scheduler does with link samples and at stop (with an in-memory transport)."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from tests.links.probes import ProbeGuard
from tests.poll import wait_for
from umbra.connectors import Input, Module, Output
from umbra.connectors.messages import Image, Message, Scalar
from umbra.connectors.ports import Sink
from umbra.modules.generic.recording import read_recording
from umbra.runtime.graph.check import check_spec
from umbra.runtime.graph.parse import parse_graph_text
from umbra.runtime.graph.plan import GraphPlan, LinkPlan
from umbra.runtime.registry import Registry
from umbra.runtime.scheduler import Scheduler, SchedulerOptions


class Frames(Module):
    image = Output(Image, doc="frames")


class Events(Module):
    """An ordered, lossless stream (operator actions are) and a state stream beside it."""

    out = Output(Scalar, events=True, doc="events")
    level = Output(Scalar, doc="a state")


class Tally(Module):
    """Remembers every value it was stepped with."""

    value = Input(Scalar, trigger=True, required=False, doc="values")
    level = Input(Scalar, trigger=True, required=False, doc="a state")
    image = Input(Image, trigger=True, required=False, doc="frames")

    def start(self) -> None:
        self.values: list[float] = []
        self.levels: list[float] = []
        self.frames: list[int] = []

    def step(self, now: float) -> None:
        if self.value.fresh:
            self.values.append(self.value.value.value)
        if self.level.fresh:
            self.levels.append(self.level.value.value)
        if self.image.fresh:
            self.frames.append(self.image.value.seq)


class Overlap(Module):
    """Records the thread of each step and fails if two steps ever overlap."""

    value = Input(Scalar, trigger=True, required=False, doc="values")

    def start(self) -> None:
        self.threads: list[int] = []
        self.values: list[float] = []
        self._inside = False

    def step(self, now: float) -> None:
        assert not self._inside, "two ticks overlapped"
        self._inside = True
        time.sleep(0.0002)  # long enough for other threads to try to come in
        self.threads.append(threading.get_ident())
        if self.value.fresh:
            self.values.append(self.value.value.value)
        self._inside = False


class Halting(Module):
    """Has a ``safe_stop`` hook."""

    out = Output(Scalar, doc="level")

    def step(self, now: float) -> None:
        self.out.send(Scalar(value=5.0))

    def safe_stop(self, now: float) -> None:
        self.out.send(Scalar(value=-1.0))


GRAPH = """
graph: inbound
clock: real
processes: {a: {}, b: {}}
modules:
  events: {type: Events, process: a, rate: 10}
  frames: {type: Frames, process: a, rate: 10}
  tally: {type: Tally, process: b}
connections:
  - events.out -> tally.value
  - events.level -> tally.level
  - frames.image -> tally.image
"""


class FakeTransport:
    """Holds the consumer's deliver callbacks so a test can push samples as zenoh would."""

    state_version = None  # cannot say when liveliness changes: asked on every tick

    def __init__(self) -> None:
        self.deliver: dict[str, Callable[[Message], None]] = {}
        self.arrived: Callable[[], None] = lambda: None

    def publisher(self, link: LinkPlan) -> Sink:
        return lambda sample, now: None

    def subscribe(
        self,
        link: LinkPlan,
        deliver: Callable[[Message], None],
        arrived: Callable[[], None] | None = None,
    ) -> None:
        def deliver_now(sample: Message) -> None:
            deliver(sample)
            if arrived is not None:
                arrived()

        self.deliver[link.connection.dst.port] = deliver_now

    def producer_alive(self, link: LinkPlan) -> bool:
        return True

    def clock_problem(self, link: LinkPlan) -> str:
        return ""

    def clock_error(self, link: LinkPlan) -> float:
        return 0.0

    def stats(self) -> dict[str, object]:
        return {}

    def close(self) -> None:
        pass


def _registry() -> Registry:
    registry = Registry()
    for cls in (Frames, Events, Tally, ProbeGuard, Halting, Overlap):
        registry.add(cls)
    return registry


def _plan(text: str) -> GraphPlan:
    return check_spec(parse_graph_text(text, "test.yaml"), _registry())


def test_events_each_get_a_step_and_state_keeps_the_latest(tmp_path: Path) -> None:
    """After a stall of the consumer: every event, in order; of a state stream (a level, video)
    only the newest, the ones it replaced counted as superseded (no backlog of the past)."""
    transport = FakeTransport()
    sched = Scheduler(
        _plan(GRAPH),
        SchedulerOptions(clock="real", duration=5.0, output_dir=tmp_path, process="b"),
        transport,
    )
    tally = sched.modules["tally"]
    # everything arrives at once, before the first tick: as after a stall of the consumer
    for i in range(1, 6):
        transport.deliver["value"](Scalar(value=float(i), seq=i))
        transport.deliver["level"](Scalar(value=10.0 * i, seq=i))
        transport.deliver["image"](Image(pixels=np.zeros((2, 2, 3), np.uint8), seq=i))

    def stop_when_done() -> None:
        deadline = time.monotonic() + 5
        while time.monotonic() < deadline and len(getattr(tally, "values", [])) < 5:
            time.sleep(0.001)
        sched.request_stop("test done", 0)  # from another thread: wakes the loop

    threading.Thread(target=stop_when_done).start()
    result = sched.run()
    assert result.reason == "test done"
    assert result.wall_time < 4.0
    assert tally.values == [1.0, 2.0, 3.0, 4.0, 5.0]  # events: every one, in order
    assert tally.levels == [50.0]  # state: the latest wins
    assert tally.frames == [5]  # video too
    superseded = result.extra["links"]["superseded"]
    assert superseded["events.level -> tally.level"] == 4
    assert superseded["frames.image -> tally.image"] == 4
    assert superseded["events.out -> tally.value"] == 0


GUARD_GRAPH = """
graph: guarded
modules:
  counter: {type: Counter, rate: 100, params: {start: 1, stop_after: 20}}
  guard: {type: ProbeGuard}
  halting: {type: Halting, rate: 100}
  record: {type: Recorder, params: {channels: [twist, level], path: rec.mcap}}
connections:
  - counter.count -> guard.value
  - guard.twist -> record.twist
  - halting.out -> record.level
"""


def test_stop_zeroes_safety_guards_and_calls_safe_stop_hooks(tmp_path: Path) -> None:
    sched = Scheduler(_plan(GUARD_GRAPH), SchedulerOptions(output_dir=tmp_path))
    result = sched.run()
    assert result.exit_code == 0
    rows = list(read_recording(tmp_path / "rec.mcap"))
    twists = [s.vector for c, s in rows if c == "twist"]
    levels = [s.value for c, s in rows if c == "level"]
    assert len(twists) == 21 and [t[0] for t in twists[:-1]] == [float(i) for i in range(1, 21)]
    np.testing.assert_array_equal(twists[-1], np.zeros(6))
    assert levels[-1] == -1.0 and set(levels[:-1]) == {5.0}


def test_zeroing_touches_float_arrays_only() -> None:
    from umbra.connectors.messages import Text, Twist
    from umbra.runtime.safe_stop import zeroed as _zeroed

    twist = Twist(vector=np.arange(1.0, 7.0), frame="tool", stamp=3.0, seq=4)
    zero = _zeroed(twist)
    assert zero is not None and zero.frame == "tool" and zero.stamp == 0.0
    np.testing.assert_array_equal(zero.vector, np.zeros(6))
    assert _zeroed(Text(text="close")) is None  # a gripper command is not repeated
    assert _zeroed(Scalar(value=1.0)) is None
    assert _zeroed(None) is None


DISPATCH_GRAPH = """
graph: dispatch
clock: real
processes: {a: {}, b: {}}
modules:
  events: {type: Events, process: a, rate: 10}   # an events stream: every sample counts
  watch: {type: Overlap, process: b, rate: 200}
connections:
  - events.out -> watch.value
"""


def _dispatch_run(
    tmp_path: Path, dispatch: str, senders: int, per_sender: int
) -> tuple[Overlap, int]:
    """Run the consumer process with ``senders`` link threads delivering ``per_sender`` values
    each; the watching module and the id of the loop's thread."""
    transport = FakeTransport()
    sched = Scheduler(
        _plan(DISPATCH_GRAPH),
        SchedulerOptions(
            clock="real", duration=10.0, output_dir=tmp_path, process="b", dispatch=dispatch
        ),
        transport,
    )
    watch = sched.modules["watch"]
    deliver = transport.deliver["value"]
    errors: list[BaseException] = []

    def send(first: int) -> None:
        # once the loop is running (and mostly idle: its module runs at 200 Hz)
        deadline = time.monotonic() + 5.0
        while not getattr(watch, "threads", None) and time.monotonic() < deadline:
            time.sleep(0.005)
        time.sleep(0.02)
        try:
            for i in range(per_sender):
                deliver(Scalar(value=float(first + i), seq=i + 1))
                time.sleep(0.002)  # the loop idle between most samples: they come inline
        except BaseException as exc:
            errors.append(exc)

    threads = [
        threading.Thread(target=send, args=(1000 * k,), name=f"link-{k}") for k in range(senders)
    ]
    for t in threads:
        t.start()

    def stop_when_done() -> None:
        for t in threads:
            t.join()
        try:  # the last values handed over to the loop are handled
            wait_for(
                lambda: len(watch.values) >= senders * per_sender,
                30.0,
                lambda: f"{senders * per_sender} values handled, found {len(watch.values)}",
            )
        except AssertionError as exc:
            errors.append(exc)
        finally:
            sched.request_stop("test done", 0)

    threading.Thread(target=stop_when_done).start()
    result = sched.run()
    assert not errors
    assert result.exit_code == 0, result.reason
    assert sorted(watch.values) == sorted(
        float(1000 * k + i) for k in range(senders) for i in range(per_sender)
    )
    return watch, threading.get_ident()  # the loop ran on this thread


def test_inline_dispatch_runs_the_tick_on_the_receiving_thread(tmp_path: Path) -> None:
    watch, loop_thread = _dispatch_run(tmp_path, "inline", senders=1, per_sender=50)
    on_link = sum(t != loop_thread for t in watch.threads)
    assert on_link >= 40  # nearly every sample handled where it arrived, not handed over


def test_inline_ticks_never_overlap_with_concurrent_links(tmp_path: Path) -> None:
    watch, _loop_thread = _dispatch_run(tmp_path, "inline", senders=3, per_sender=100)
    assert len(set(watch.threads)) >= 2  # the loop and at least one link thread took part


def test_loop_dispatch_keeps_every_step_on_the_loop_thread(tmp_path: Path) -> None:
    watch, loop_thread = _dispatch_run(tmp_path, "loop", senders=2, per_sender=30)
    assert set(watch.threads) == {loop_thread}
