"""One loop per process: modules at their rate or on their triggers, in data order.

Every tick, in the graph's data order, a module runs when its rate makes it due or when one of its
trigger inputs received a new sample earlier in the same tick — so a sample crosses a chain in one
tick. Delayed connections (``~>``) are written after the tick, so their consumers read the previous
tick's value. Link samples from other processes are written into registers at the start of a tick
(``umbra.runtime.link_inbox``: events one per register per tick, in order; state the newest).

Before each step the module's :class:`~umbra.connectors.ports.OriginTrack` is reset, so what it
sends takes the oldest origin among the inputs it reads in that step.

Reacting to a link sample (``dispatch: inline``, the default on the real clock): when a sample
arrives while the loop is idle, waiting for its next due time, the tick runs at once on the thread
that received the sample (zenoh's), instead of waking the loop's thread — a thread hand-over costs
tens of microseconds per hop. Ticks never overlap: one lock serialises them, whichever thread runs
them, so a module still never sees concurrency. When the loop is busy the sample waits for the end
of its tick, as with ``dispatch: loop``, which always hands samples to the loop's thread (use it
when a module must run on one thread, or steps that block would hold zenoh's receive thread).

When the loop ends, for any reason, the runtime first puts outputs in a safe state
(``umbra.runtime.safe_stop``), then stops the modules. While it runs the process holds what
``umbra.runtime.process_holds`` takes (CPU latency, priority, a frozen heap).
"""

from __future__ import annotations

import math
import threading
import time
import zlib
from collections import deque
from collections.abc import Callable
from typing import Any

import numpy as np

from umbra.connectors.errors import ModuleFailed, UserError
from umbra.connectors.messages import Message
from umbra.connectors.module import Module, ModuleContext
from umbra.connectors.ports import Register
from umbra.runtime.clock import make_clock
from umbra.runtime.graph.plan import GraphPlan
from umbra.runtime.link_inbox import drain
from umbra.runtime.links_api import LinkTransport
from umbra.runtime.process_holds import ProcessHolds
from umbra.runtime.run_options import INTERRUPTED, SchedulerOptions, StopRequest
from umbra.runtime.safe_stop import Slot, safe_stop
from umbra.runtime.stats import ModuleStats, RunResult
from umbra.runtime.stop_signals import install_stop_signals, restore_signals

#: At most this many ticks in a row on a link's thread before the rest is left to the loop.
REACT_ROUNDS = 16

__all__ = ["INTERRUPTED", "Scheduler", "SchedulerOptions", "StopRequest"]


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
        outside = transport is not None or options.ros2 is not None  # samples from other threads
        self._wake = threading.Event() if outside else None
        self._link_regs: list[tuple[Register[Any], Any]] = []
        self._link_state = -1  # the transport's state_version the link registers reflect
        self._clocks_read_at = -math.inf  # when the registers' clock_error was last set
        self._tick_lock = threading.Lock()  # one tick at a time, whichever thread runs it
        self._inline = outside and options.dispatch == "inline" and (options.clock == "real")
        self._running = False  # ticks may run (set and cleared under the tick lock)
        self._ticks = 0
        self._t0 = 0.0
        self._failure: ModuleFailed | None = None
        self.modules: dict[str, Module[Any]] = {}
        self._slots: list[Slot] = []
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
                attended=self.options.attended,
            )
            module = mplan.cls(name, mplan.params, context)
            module.bind_ports(self.tick_time)
            self.modules[name] = module
        self._wire()
        self.ros2: Any = None  # the ROS 2 node of this process (``umbra.runtime.ros2.run_bridge``)
        if self.options.ros2 is not None:
            from umbra.runtime.ros2.run_bridge import attach_ros2

            self.ros2 = attach_ros2(self, self.options.ros2)
        self.recorder: Any = None
        record = self.options.record or getattr(self.plan.spec, "record", None)
        if record is not None and record.enabled:
            from umbra.runtime.recording.tap import RunRecorder

            self.recorder = RunRecorder(
                self.plan,
                self.modules,
                record,
                process=self.options.process,
                output_dir=self.options.output_dir,
                clock_kind=self.clock.kind,
                now=self.clock.now(),
                log=self.options.log,
            )
        from umbra.runtime.tuning import CHANGES_TOPIC, Tuner

        #: live changes of tunable parameters, applied at the start of a tick
        self.tuner = Tuner(self.modules, log)
        if self.recorder is not None:
            self.tuner.record = self.recorder.file.sink(CHANGES_TOPIC)
        for name in names:
            mplan = self.plan.modules[name]
            module = self.modules[name]
            period = 1.0 / mplan.spec.rate if mplan.spec.rate else None
            self._slots.append(
                Slot(
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
                reg.connected = out.connected = True
                if conn.delayed:
                    out.sinks.append(self._delayed_writer(reg))
                else:
                    out.sinks.append(reg.write)
            elif link is not None and self.transport is not None:
                if src_here:
                    out = self.modules[conn.src.module].outputs[conn.src.port]
                    out.connected = True
                    out.sinks.append(self.transport.publisher(link))
                if dst_here:
                    reg = self.modules[conn.dst.module].registers[conn.dst.port]
                    reg.events = link.reliable
                    reg.connected = True
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
        started: list[Slot] = []
        old_handlers = (
            install_stop_signals(self.request_stop) if self.options.handle_signals else {}
        )
        lateness: list[float] = []
        ticks = 0
        failure: ModuleFailed | None = None
        user_error: UserError | None = None
        opts = self.options
        holds = ProcessHolds(
            self.plan, opts.process, self.clock.kind, opts.cpu_latency_us, opts.log
        )
        holds.acquire()
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
            safe_stop(started, self.clock.now(), self.options.log)
            for slot in reversed(started):
                try:
                    slot.module.stop()
                except Exception as exc:  # stop must run for every module
                    if failure is None:
                        failure = ModuleFailed(
                            slot.module.name, slot.stats.type_name, "stop", ticks, exc
                        )
            holds.release()
            restore_signals(old_handlers)
            if self.ros2 is not None:
                self.ros2.close()  # after the safe stop: its zeros reach ROS 2 too
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
        extra.update(holds.summary())
        if self.ros2 is not None:
            extra["ros2"] = self.ros2.summary()
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
            elif drain(inbound, now) and self._wake is not None:
                self._wake.set()  # events left for the next tick: it follows at once
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
        alive, error, problem = (
            transport.producer_alive,
            transport.clock_error,
            transport.clock_problem,
        )
        for reg, link in self._link_regs:
            reg.set_link_alive(alive(link))
            reg.clock_error = error(link)
            reg.clock_problem = problem(link)
