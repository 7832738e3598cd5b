"""What a process holds while its loop runs, and gives back after: the CPU's wake-up latency
(``umbra.runtime.realtime``), a real-time priority or a lower one for a process that gives way
(``umbra.runtime.rt_priority``), and a frozen heap (``umbra.runtime.gc_pause``). Each is for the
real clock only: on the sim clock nothing waits for a CPU."""

from __future__ import annotations

from typing import Any

from umbra.runtime.gc_pause import HeapFreeze
from umbra.runtime.graph.plan import GraphPlan
from umbra.runtime.realtime import CpuLatencyHold
from umbra.runtime.rt_priority import GiveWay, RealtimePriority, priority_for

#: Why a sim-clock run holds no CPU latency it was asked for (what its summary says).
SIM_CLOCK_NO_LATENCY = "sim clock: nothing waits for a CPU to wake"
#: Why a sim-clock run takes no real-time priority it was asked for.
SIM_CLOCK_NO_PRIORITY = "sim clock: nothing waits for a CPU"


class ProcessHolds:
    """The holds of process ``process`` (None: the whole graph in one) of ``plan``."""

    def __init__(
        self,
        plan: GraphPlan,
        process: str | None,
        clock_kind: str,
        cpu_latency_us: int | None,
        log: Any,
    ) -> None:
        real = clock_kind == "real"
        self.latency = CpuLatencyHold(
            cpu_latency_us, log, unneeded="" if real else SIM_CLOCK_NO_LATENCY
        )
        self.priority = RealtimePriority(
            priority_for(plan.spec.realtime_priority, process),
            log,
            unneeded="" if real else SIM_CLOCK_NO_PRIORITY,
        )
        self.give_way = GiveWay(  # a process of its own only: in one process the servo lives too
            plan.spec.nice.get(process or "") if process is not None and real else None, log
        )
        # no full collection mid-loop; taken before t0, so the collection takes no time of the run
        self.heap = HeapFreeze(enabled=real)

    def acquire(self) -> None:
        for hold in (self.latency, self.priority, self.give_way, self.heap):
            hold.acquire()

    def release(self) -> None:
        """Give back the heap, the priority and the latency (the niceness stays: it only gives)."""
        self.heap.release()
        self.priority.release()
        self.latency.release()

    def summary(self) -> dict[str, Any]:
        """The run summary's entries of the holds in force."""
        extra: dict[str, Any] = {}
        if self.latency.limit_us is not None:
            extra["realtime"] = self.latency.summary()
        if self.priority.priority is not None:
            extra["realtime_priority"] = self.priority.summary()
        if self.give_way.nice is not None:
            extra["give_way"] = self.give_way.summary()
        if self.heap.enabled:
            extra["gc"] = self.heap.summary()
        return extra
