"""One loop per process: modules at their rate or on their triggers, in data order.

Every tick, in the graph's data order, a module runs when its rate makes it due or when one of its
trigger inputs received a new sample earlier in the same tick — so a sample crosses a chain in one
tick. Delayed connections (``~>``) are written after the tick, so their consumers read the previous
tick's value. Link samples from other processes are written into registers at the start of a tick:
on an events link (declared ``events`` on its output: operator actions, gripper, paths) one sample
per register per tick, in order (the rest wait for the next tick, which follows at once), so a
consumer sees every event as it would in one process; on a state link (everything else: images,
contours, poses, joint states, statuses, twists) the newest sample wins and the ones it replaced
are counted (``superseded``), so a starved consumer catches up at once instead of working through
a backlog of the past.

Before each step the module's :class:`~connectors.ports.OriginTrack` is reset, so what it sends
takes the oldest origin among the inputs it reads in that step.

Reacting to a link sample (``dispatch: inline``, the default on the real clock): when a sample
arrives while the loop is idle, waiting for its next due time, the tick runs at once on the thread
that received the sample (zenoh's), instead of waking the loop's thread — a thread hand-over costs
tens of microseconds per hop. Ticks never overlap: one lock serialises them, whichever thread runs
them, so a module still never sees concurrency. When the loop is busy the sample waits for the end
of its tick, as with ``dispatch: loop``, which always hands samples to the loop's thread (use it
when a module must run on one thread, or steps that block would hold zenoh's receive thread).

When the loop ends, for any reason, the runtime first puts outputs in a safe state, then stops the
modules: each module that defines ``safe_stop(now)`` has it called (in data order), each
``SAFETY_GUARD`` module without one has its numeric-array outputs (a twist, joint rates) sent
once more as zeros, and the modules those samples trigger run once so the zero reaches the drives.
"""

from __future__ import annotations

import math
import signal
import threading
import time
import zlib
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import msgspec
import numpy as np

from connectors.errors import ModuleFailed, UserError
from connectors.messages import Message
from connectors.module import Module, ModuleContext
from connectors.ports import OriginTrack, Register
from runtime.clock import make_clock
from runtime.gc_pause import HeapFreeze
from runtime.graph.plan import GraphPlan
from runtime.links_api import LinkTransport
from runtime.realtime import CpuLatencyHold
from runtime.rt_priority import GiveWay, RealtimePriority, priority_for
from runtime.stats import ModuleStats, RunResult

INTERRUPTED = 130
#: Why a sim-clock run holds no CPU latency it was asked for (what its summary says).
SIM_CLOCK_NO_LATENCY = "sim clock: nothing waits for a CPU to wake"
#: Why a sim-clock run takes no real-time priority it was asked for.
SIM_CLOCK_NO_PRIORITY = "sim clock: nothing waits for a CPU"
#: At most this many ticks in a row on a link's thread before the rest is left to the loop.
REACT_ROUNDS = 16


@dataclass
class _Slot:
    """A module in the loop: its schedule and counters."""

    module: Module
    stats: ModuleStats
    period: float | None
    next_due: float
    k: int
    trigger_regs: list[Register[Any]]
    all_regs: list[Register[Any]]
    track: OriginTrack


@dataclass
class StopRequest:
    """Why the loop should end after the current tick, and with which exit status."""

    reason: str
    exit_code: int


@dataclass
class SchedulerOptions:
    """How to run: clock, duration [s], output folder, process, signal handling."""

    clock: str = "sim"
    duration: float | None = None
    output_dir: Path = field(default_factory=lambda: Path("."))
    process: str | None = None  # None: every module (single process)
    handle_signals: bool = False
    max_ticks: int | None = None
    log: Any = None
    #: "inline": a link sample arriving while the loop is idle is handled at once on the thread
    #: that received it; "loop": always on the loop's thread (see the module docstring).
    dispatch: str = "inline"
    #: the CPU wake-up latency [µs] held while the loop runs (``runtime.realtime``); None: none
    cpu_latency_us: int | None = None
    #: record every output of this process (``runtime.recording.tap``); None:
    #: as the graph's ``record:`` says
    record: Any = None


class Scheduler:
    """Builds the modules of one process from a checked graph and runs them."""

    def __init__(
        self, plan: GraphPlan, options: SchedulerOptions, transport: LinkTransport | None = None
    ) -> None:
        self.plan = plan
        self.options = options
        self.clock = make_clock(options.clock)
        self.transport = transport
        self.process_name = options.process or "main"
        self._stop: StopRequest | None = None
        self._tick_now = self.clock.now()
        self._pending: list[tuple[Register[Any], Message, float]] = []
        self._inbound: deque[tuple[Register[Any], Message, bool]] = deque()
        self._wake = threading.Event() if transport is not None else None
        self._link_regs: list[tuple[Register[Any], Any]] = []
        self._link_state = -1  # the transport's state_version the link registers reflect
        self._clocks_read_at = -math.inf  # when the registers' clock_error was last set
        self._tick_lock = threading.Lock()  # one tick at a time, whichever thread runs it
        self._inline = (
            transport is not None and options.dispatch == "inline" and (options.clock == "real")
        )
        self._running = False  # ticks may run (set and cleared under the tick lock)
        self._ticks = 0
        self._t0 = 0.0
        self._failure: ModuleFailed | None = None
        self.modules: dict[str, Module] = {}
        self._slots: list[_Slot] = []
        self._build()

    # -- construction ----------------------------------------------------------------------------
    def _build(self) -> None:
        import logging

        log = self.options.log or logging.getLogger("umbra")
        names = self.plan.modules_in(self.options.process)
        if not names:
            raise UserError(
                f"process `{self.options.process}` has no modules "
                f"(processes: {', '.join(self.plan.processes)})"
            )
        for name in names:
            mplan = self.plan.modules[name]
            seed = (self.plan.spec.seed * 1_000_003 + zlib.crc32(name.encode())) % 2**32
            context = ModuleContext(
                graph=self.plan.spec.name,
                frames=self.plan.frames,
                output_dir=self.options.output_dir,
                rng=np.random.default_rng(seed),
                clock=self.clock.kind,
                log=log,
                request_stop=self.request_stop,
                process=mplan.process,
            )
            module = mplan.cls(name, mplan.params, context)
            module.bind_ports(self.tick_time)
            self.modules[name] = module
        self._wire()
        self.recorder: Any = None
        record = self.options.record or getattr(self.plan.spec, "record", None)
        if record is not None and record.enabled:
            from runtime.recording.tap import RunRecorder

            self.recorder = RunRecorder(self, record)
        from runtime.tuning import CHANGES_TOPIC, Tuner

        #: live changes of tunable parameters, applied at the start of a tick
        self.tuner = Tuner(self.modules, log)
        if self.recorder is not None:
            self.tuner.record = self.recorder.file.sink(CHANGES_TOPIC)
        for name in names:
            mplan = self.plan.modules[name]
            module = self.modules[name]
            period = 1.0 / mplan.spec.rate if mplan.spec.rate else None
            self._slots.append(
                _Slot(
                    module=module,
                    stats=ModuleStats(name, mplan.spec.type),
                    period=period,
                    next_due=0.0,
                    k=0,
                    trigger_regs=[module.registers[t] for t in mplan.triggers],
                    all_regs=list(module.registers.values()),
                    track=module.origin_track,
                )
            )

    def _wire(self) -> None:
        local = set(self.modules)
        links = {id(link.connection): link for link in self.plan.links}
        for conn in self.plan.connections:
            src_here, dst_here = conn.src.module in local, conn.dst.module in local
            link = links.get(id(conn)) if self.options.process is not None else None
            if src_here and dst_here and link is None:
                out = self.modules[conn.src.module].outputs[conn.src.port]
                reg = self.modules[conn.dst.module].registers[conn.dst.port]
                reg.events = out.events
                if conn.delayed:
                    out.sinks.append(self._delayed_writer(reg))
                else:
                    out.sinks.append(reg.write)
            elif link is not None and self.transport is not None:
                if src_here:
                    out = self.modules[conn.src.module].outputs[conn.src.port]
                    out.sinks.append(self.transport.publisher(link))
                if dst_here:
                    reg = self.modules[conn.dst.module].registers[conn.dst.port]
                    reg.events = link.reliable
                    self.transport.subscribe(
                        link, self._deliverer(reg, link.reliable), self._arrived
                    )
                    self._link_regs.append((reg, link))

    def _delayed_writer(self, reg: Register[Any]) -> Callable[[Message, float], None]:
        pending = self._pending

        def write_later(sample: Message, now: float) -> None:
            pending.append((reg, sample, now))

        return write_later

    def _deliverer(self, reg: Register[Any], in_order: bool = True) -> Callable[[Message], None]:
        inbound = self._inbound

        def deliver(sample: Message) -> None:
            inbound.append((reg, sample, in_order))

        return deliver

    def _arrived(self) -> None:
        """Called by the transport once a sample is queued for every register it feeds: tick now
        on this thread when the loop is idle (``dispatch: inline``; at most ``REACT_ROUNDS``
        ticks while samples wait), else wake the loop."""
        if self._inline and self._running and self._tick_lock.acquire(blocking=False):
            try:
                inbound, now = self._inbound, self.clock.now
                for _ in range(REACT_ROUNDS):
                    if not inbound or not self._running or self._stop is not None:
                        break
                    self._tick(now())
            except Exception as exc:  # a bug in the runtime, never a module's failure (caught)
                self.request_stop(f"internal error handling a link sample: {exc!r}", 1)
            finally:
                self._tick_lock.release()
            if not self._inbound:
                return
        wake = self._wake
        if wake is not None and not wake.is_set():
            wake.set()

    def tick_time(self) -> float:
        """The current tick's time [s]: what unstamped samples are stamped with."""
        return self._tick_now

    # -- control ---------------------------------------------------------------------------------
    def request_stop(self, reason: str, exit_code: int = 0) -> None:
        """End the run after the current tick (first request wins). Safe from any thread: a loop
        waiting for its next tick wakes up."""
        if self._stop is None:
            self._stop = StopRequest(reason, exit_code)
        if self._wake is not None:
            self._wake.set()

    def _duration_outcome(self, duration: float | None) -> tuple[str, int]:
        """Reason and exit status of a run that reached its duration: 0 unless a module (a judge
        such as World) says the run had not succeeded by then."""
        reason = f"duration {duration:g} s reached"
        for name, module in self.modules.items():
            outcome = module.outcome_at_duration()
            if outcome is not None and outcome[0] != 0:
                return f"{reason}; {name}: {outcome[1]}", outcome[0]
        return reason, 0

    @property
    def pending_link_samples(self) -> int:
        """Link samples received but not yet written into registers."""
        return len(self._inbound)

    # -- the loop --------------------------------------------------------------------------------
    def run(self) -> RunResult:
        """Start every module, loop until a stop, stop every started module; never raises for a
        module's failure (the result says what happened)."""
        wall0 = time.monotonic()
        started: list[_Slot] = []
        old_handlers = self._install_signals()
        lateness: list[float] = []
        ticks = 0
        failure: ModuleFailed | None = None
        user_error: UserError | None = None
        hold = CpuLatencyHold(
            self.options.cpu_latency_us,
            self.options.log,
            unneeded="" if self.clock.kind == "real" else SIM_CLOCK_NO_LATENCY,
        )
        hold.acquire()
        priority = RealtimePriority(
            priority_for(self.plan.spec.realtime_priority, self.options.process),
            self.options.log,
            unneeded="" if self.clock.kind == "real" else SIM_CLOCK_NO_PRIORITY,
        )
        priority.acquire()
        give_way = GiveWay(  # a process of its own only: in one process the servo lives too
            self.plan.spec.nice.get(self.options.process or "")
            if self.options.process is not None and self.clock.kind == "real"
            else None,
            self.options.log,
        )
        give_way.acquire()
        # no full collection mid-loop; before t0, so the collection takes no time of the run
        heap = HeapFreeze(enabled=self.clock.kind == "real")
        heap.acquire()
        t0 = self.clock.now()
        if self.recorder is not None:
            self.recorder.start(t0)
        try:
            for slot in self._slots:
                try:
                    slot.module.start()
                except UserError as exc:
                    user_error = exc
                    break
                except Exception as exc:
                    failure = ModuleFailed(slot.module.name, slot.stats.type_name, "start", 0, exc)
                    break
                started.append(slot)
            if failure is None and user_error is None:
                for slot in self._slots:
                    slot.next_due = t0
                ticks, failure = self._loop(t0, lateness)
        finally:
            self._safe_stop(started)
            for slot in reversed(started):
                try:
                    slot.module.stop()
                except Exception as exc:  # stop must run for every module
                    if failure is None:
                        failure = ModuleFailed(
                            slot.module.name, slot.stats.type_name, "stop", ticks, exc
                        )
            heap.release()
            priority.release()
            hold.release()
            self._restore_signals(old_handlers)
            if self.recorder is not None:
                self.recorder.close()  # after the modules: the safe-stop zeros are recorded
        if user_error is not None:
            raise user_error
        for slot in self._slots:
            slot.stats.violations = sum(r.violations for r in slot.all_regs)
            try:
                slot.stats.extra = dict(slot.module.summary())
            except Exception as exc:
                slot.stats.extra = {"summary_error": f"{type(exc).__name__}: {exc}"}
        if failure is not None:
            code, reason = 1, str(failure)
        elif self._stop is not None:
            code, reason = self._stop.exit_code, self._stop.reason
        else:
            code, reason = 0, "finished"
        extra: dict[str, Any] = {}
        if self.transport is not None:
            extra["links"] = self.transport.stats()
            extra["links"]["superseded"] = {
                str(link.connection): reg.superseded for reg, link in self._link_regs
            }
        if hold.limit_us is not None:
            extra["realtime"] = hold.summary()
        if priority.priority is not None:
            extra["realtime_priority"] = priority.summary()
        if give_way.nice is not None:
            extra["give_way"] = give_way.summary()
        if heap.enabled:
            extra["gc"] = heap.summary()
        if self.recorder is not None:
            extra["recording"] = self.recorder.summary()
        return RunResult(
            process=self.process_name,
            exit_code=code,
            reason=reason,
            ticks=ticks,
            sim_time=self.clock.now() - t0,
            wall_time=time.monotonic() - wall0,
            modules=[s.stats for s in self._slots],
            lateness_s=np.asarray(lateness),
            extra=extra,
        )

    def _loop(self, t0: float, lateness: list[float]) -> tuple[int, ModuleFailed | None]:
        clock, rated = self.clock, [s for s in self._slots if s.period is not None]
        duration = self.options.duration
        end = t0 + duration if duration is not None else math.inf
        max_ticks = self.options.max_ticks or math.inf
        real = clock.kind == "real"
        lock, wake = self._tick_lock, self._wake
        self._t0 = t0
        if not rated and self.transport is None:
            self.request_stop("nothing to schedule (no module has a rate)", 0)
        with lock:
            self._running = True
        try:
            while self._stop is None and self._ticks < max_ticks:
                due = min((s.next_due for s in rated), default=clock.now() + 0.01)
                if due >= end - 1e-9:
                    if real:
                        clock.wait_until(end, wake)
                    self.request_stop(*self._duration_outcome(duration))
                    break
                clock.wait_until(due, wake)
                with lock:
                    if self._stop is not None:
                        break
                    now = clock.now()
                    if real and rated:
                        lateness.append(max(0.0, now - due))
                    self._tick(now)
        finally:
            with lock:
                self._running = False
        return self._ticks, self._failure

    def _tick(self, now: float) -> None:
        """One tick at ``now`` [s]: link samples into registers, then every due or triggered
        module in data order, then delayed writes. Call with the tick lock held."""
        self._tick_now = now
        if self.tuner.pending:  # between steps: never under a module's feet
            self.tuner.apply(now)
        inbound = self._inbound
        if inbound:
            if len(inbound) == 1:  # the usual case: one sample since the last tick
                reg, sample, _in_order = inbound.popleft()
                reg.write(sample, now)
            else:
                self._drain(now)
        self._ticks += 1
        perf = time.perf_counter_ns
        t0 = self._t0
        for slot in self._slots:
            run_it = False
            if slot.period is not None and slot.next_due <= now + 1e-12:
                run_it = True
                slot.k += 1
                slot.next_due = t0 + slot.k * slot.period
                if slot.next_due <= now:  # fell a whole period behind: count and skip ahead
                    missed = int((now - slot.next_due) / slot.period) + 1
                    slot.stats.misses += missed
                    slot.k += missed
                    slot.next_due = t0 + slot.k * slot.period
            if not run_it:
                for reg in slot.trigger_regs:
                    if reg.fresh:
                        run_it = True
                        break
            if not run_it:
                continue
            slot.track.reset()
            start = perf()
            try:
                slot.module.step(now)
            except Exception as exc:
                self._failure = ModuleFailed(
                    slot.module.name, slot.stats.type_name, "step", self._ticks, exc
                )
                self.request_stop(str(self._failure), 1)
                return
            spent = perf() - start
            stats = slot.stats
            stats.calls += 1
            stats.total_ns += spent
            if spent > stats.max_ns:
                stats.max_ns = spent
            for reg in slot.all_regs:
                reg.fresh = False
        pending = self._pending
        if pending:
            for reg, sample, when in pending:
                reg.write(sample, when)
            pending.clear()
        transport = self.transport
        if transport is not None and (
            transport.state_version != self._link_state or now >= self._clocks_read_at + 1.0
        ):
            self._update_link_states(transport, now)  # None (cannot say) is never equal

    def _update_link_states(self, transport: LinkTransport, now: float) -> None:
        """``link_alive`` and ``clock_error`` of each register fed by a link; called when the
        transport says a producer's liveliness or an end of stream changed (every tick when it
        cannot say), and every second for the clocks' error bounds."""
        version = transport.state_version
        self._link_state = -1 if version is None else version
        self._clocks_read_at = now
        alive, error = transport.producer_alive, transport.clock_error
        for reg, link in self._link_regs:
            reg.link_alive = alive(link)
            reg.clock_error = error(link)

    def _drain(self, now: float) -> None:
        """Several samples since the last tick: on an events link one per register, in order
        (the rest wait for the next tick); on a state link the newest wins and the samples it
        replaced are counted as ``superseded``."""
        inbound = self._inbound
        written: set[int] = set()
        held = []
        for _ in range(len(inbound)):  # samples arriving meanwhile wait for the next tick
            item = inbound.popleft()
            reg, sample, in_order = item
            if id(reg) in written:
                if in_order:
                    held.append(item)
                    continue
                reg.superseded += 1
            reg.write(sample, now)
            written.add(id(reg))
        if held:
            inbound.extendleft(reversed(held))
            if self._wake is not None:
                self._wake.set()

    # -- safe stop -------------------------------------------------------------------------------
    def _safe_stop(self, started: list[_Slot]) -> None:
        """Zero commands before anything stops: ``safe_stop`` hooks, zeros from safety guards, then
        one pass of the modules those samples trigger. Failures are logged, never raised."""
        import logging

        log = self.options.log or logging.getLogger("umbra")
        now = self.clock.now()
        sent = False
        for slot in started:
            module = slot.module
            hook = getattr(module, "safe_stop", None)
            try:
                slot.track.reset()
                if callable(hook):
                    hook(now)
                    sent = True
                elif module.SAFETY_GUARD:
                    for port in module.outputs.values():
                        zero = _zeroed(port.last)
                        if zero is not None:
                            port.send(zero)
                            sent = True
                            log.info("safe stop: `%s.%s` sent zero", module.name, port.name)
            except Exception as exc:
                log.error("safe stop of `%s` failed: %s: %s", module.name, type(exc).__name__, exc)
        if not sent:
            return
        for slot in started:
            if any(reg.fresh for reg in slot.trigger_regs):
                slot.track.reset()
                try:
                    slot.module.step(now)
                except Exception as exc:
                    log.error(
                        "safe stop: `%s` failed passing the zero on: %s: %s",
                        slot.module.name,
                        type(exc).__name__,
                        exc,
                    )
                for reg in slot.all_regs:
                    reg.fresh = False

    # -- signals ---------------------------------------------------------------------------------
    def _install_signals(self) -> dict[int, Any]:
        if (
            not self.options.handle_signals
            or threading.current_thread() is not threading.main_thread()
        ):
            return {}
        old = {}

        def on_signal(signum: int, frame: Any) -> None:
            name = signal.Signals(signum).name
            if signum == signal.SIGTSTP:  # Ctrl-Z: a suspended loop cannot watch the arm
                self.request_stop("suspended by Ctrl-Z (SIGTSTP): stopped safely instead", 130)
            else:
                self.request_stop(f"interrupted by {name}", INTERRUPTED)
            if self._wake is not None:
                self._wake.set()

        for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGTSTP):
            old[sig] = signal.signal(sig, on_signal)
        return old

    @staticmethod
    def _restore_signals(old: dict[int, Any]) -> None:
        for sig, handler in old.items():
            signal.signal(sig, handler)


def _zeroed(sample: Message | None) -> Message | None:
    """``sample`` with every floating-point array zeroed and a fresh stamp, or None when it has
    no such array (text, status: nothing to zero, nothing re-sent)."""
    if sample is None:
        return None
    zeros = {
        name: np.zeros_like(value)
        for name in sample.__struct_fields__
        if isinstance(value := getattr(sample, name), np.ndarray) and value.dtype.kind in "fc"
    }
    if not zeros:
        return None
    return msgspec.structs.replace(sample, stamp=0.0, **zeros)
