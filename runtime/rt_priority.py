"""Real-time scheduling for a process that closes a servo loop (Linux ``SCHED_FIFO``).

On a shared host the servo process competes with everything else for the CPUs: a browser
drawing the operator's 3-D view in software, a recording being compressed, a compiler. Under the
default policy (``SCHED_OTHER``) the kernel shares the CPUs out fairly, so the servo tick waits
its turn and is late. A ``SCHED_FIFO`` thread runs as soon as it is ready and keeps the CPU until
it blocks, ahead of every ``SCHED_OTHER`` thread — what ``cyclictest``, ros2_control's
``thread_priority`` and OROCOS's real-time activities use. The kernel still keeps 5 % of each
second for other work (``/proc/sys/kernel/sched_rt_runtime_us``), so a runaway loop cannot
lock the machine.

The policy is set on every thread the process has when the loop starts (the scheduler's, and
the link threads that run triggered modules on arrival), and threads they start later inherit
it. Setting it needs root or ``CAP_SYS_NICE`` (or an ``rtprio`` limit from
``/etc/security/limits.conf``); a process that cannot says why once and runs anyway, and its
summary records it.
"""

from __future__ import annotations

import contextlib
import logging
import os
import sys
from typing import Any

from umbra.connectors.threads import BACKGROUND_POLICIES, background, lowered

__all__ = ["BACKGROUND_POLICIES", "RealtimePriority", "background", "lowered", "priority_for"]

#: Longest a thread holds the GIL while another waits for it, in a real-time process [s]
#: (Python's default is 5 ms: a whole servo period at 200 Hz).
GIL_SWITCH_S = 0.0005

#: The priorities ``SCHED_FIFO`` takes on Linux (higher runs first).
MIN_PRIORITY = 1
MAX_PRIORITY = 99
TASKS = "/proc/self/task"
#: Most looks at the process's threads when moving them (each finds those started during the
#: last; a process that starts threads faster than they are moved is held after the last)
_LOOKS = 10


def is_priority(value: object) -> bool:
    """Whether ``value`` is a ``SCHED_FIFO`` priority: a whole number from 1 to 99."""
    return (
        isinstance(value, int)
        and not isinstance(value, bool)
        and MIN_PRIORITY <= value <= MAX_PRIORITY
    )


def _threads() -> list[int]:
    """The kernel ids of this process's threads."""
    try:
        return [int(tid) for tid in os.listdir(TASKS)]
    except OSError:
        return [0]  # no /proc: the calling thread only


class RealtimePriority:
    """From ``acquire()`` to ``release()``, runs every thread of this process under
    ``SCHED_FIFO`` at ``priority`` (1–99); ``None`` asks nothing, and neither does one given an
    ``unneeded`` reason. Never raises for a host that refuses: ``held`` and ``reason`` say what
    happened, ``summary()`` goes into the run summary."""

    def __init__(
        self, priority: int | None, log: logging.Logger | None = None, unneeded: str = ""
    ) -> None:
        self.priority = priority
        self.held = False
        self.reason = unneeded
        self._log = log or logging.getLogger("umbra")
        self._before: dict[int, tuple[int, int]] = {}  # thread -> its policy and priority
        self._switch_before: float | None = None  #: the GIL switch interval before [s]

    def acquire(self) -> None:
        """Put every thread of the process under ``SCHED_FIFO`` (all or none)."""
        if self.priority is None or self.reason:
            return
        param = os.sched_param(self.priority)
        looked: set[int] = set()
        try:
            # again while a look finds threads the last one did not: a thread not moved yet may
            # start one meanwhile, under its own policy (a zenoh session opening a link)
            for _ in range(_LOOKS):
                new = [tid for tid in _threads() if tid not in looked]
                if not new:
                    break
                looked.update(new)
                for tid in new:
                    try:
                        before = (os.sched_getscheduler(tid), os.sched_getparam(tid).sched_priority)
                        if before[0] in BACKGROUND_POLICIES:
                            continue  # it asked for the background (a recorder): it stays there
                        os.sched_setscheduler(tid, os.SCHED_FIFO, param)
                    except ProcessLookupError:
                        continue  # the thread ended meanwhile
                    self._before[tid] = before
        except OSError as exc:
            self.reason = f"cannot set SCHED_FIFO: {exc.strerror or exc}"
            self.release()
            self._log.warning(
                "realtime_priority %d not held (%s; it needs root, CAP_SYS_NICE or an rtprio "
                "limit): running under the default policy",
                self.priority,
                self.reason,
            )
            return
        self.held = True
        # a thread beside the loop (a recording's writer) holds the GIL at most this long while
        # the loop waits for it; it runs under SCHED_FIFO too, so it is never off the CPU then
        self._switch_before = sys.getswitchinterval()
        sys.setswitchinterval(GIL_SWITCH_S)
        self._log.info(
            "running %d threads under SCHED_FIFO priority %d", len(self._before), self.priority
        )

    def release(self) -> None:
        """Every thread that was moved back to the policy it had; threads started meanwhile
        (they inherited the real-time policy) to the default one."""
        if self._switch_before is not None:
            sys.setswitchinterval(self._switch_before)
            self._switch_before = None
        if not self._before:
            return
        for tid in {*self._before, *_threads()}:
            policy, priority = self._before.get(tid, (os.SCHED_OTHER, 0))
            try:
                os.sched_setscheduler(tid, policy, os.sched_param(priority))
            except OSError:
                continue  # ended meanwhile
        self._before = {}

    def summary(self) -> dict[str, Any]:
        """What the run summary says: the priority asked, whether the run held it, why not."""
        out: dict[str, Any] = {"realtime_priority": self.priority, "held": self.held}
        if self.reason:
            out["reason"] = self.reason
        return out


def priority_for(requests: dict[str, int], process: str | None) -> int | None:
    """The priority a process runs at: what the graph asks for ``process``; with every module
    in one process (``process`` None), the highest any process asks. None: the default policy."""
    if process is not None:
        return requests.get(process)
    return max(requests.values(), default=None)


#: Highest ``nice`` a graph may ask for a process (Linux's range ends at 19).
MAX_NICE = 19


def is_nice(value: object) -> bool:
    """A ``nice`` setting a graph may give a process: a whole number from 0 to ``MAX_NICE``."""
    return isinstance(value, int) and not isinstance(value, bool) and 0 <= value <= MAX_NICE


class GiveWay:
    """Every thread of the process in the background (``SCHED_BATCH`` at ``nice``), and those
    it starts later too (they inherit it): a process that gives way under CPU starvation, such
    as the operator's pages, whose frame rate must give before the control path's freshness."""

    def __init__(self, nice: int | None, log: logging.Logger | None = None) -> None:
        self.nice = nice
        self.held = False
        self._log = log or logging.getLogger("umbra")

    def acquire(self) -> None:
        if self.nice is None:
            return
        for tid in _threads():
            with contextlib.suppress(AttributeError, OSError):
                os.sched_setscheduler(tid, os.SCHED_BATCH, os.sched_param(0))
            with contextlib.suppress(OSError):
                os.setpriority(os.PRIO_PROCESS, tid, self.nice)
        self.held = True
        self._log.info("giving way: threads under SCHED_BATCH at nice %d", self.nice)

    def summary(self) -> dict[str, Any]:
        return {"nice": self.nice, "held": self.held}
