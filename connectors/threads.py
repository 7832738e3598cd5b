"""Threads a module starts for work that must give way: a video encoder, a recording writer.

A module's device readers and encoders run beside the scheduler's loop. Work whose only cost of
falling behind is a dropped or late frame in a file (never the freshness of the control path)
puts its thread in the background, so that under CPU starvation it gives way first.

Except in a real-time process. Its threads share one GIL with the loop, so a helper the kernel
has put behind other work while it holds the GIL stalls the loop until it runs again: priority
inversion through the GIL. Measured with the split pick-up recording (`bench_record.py`): the
servo process's writer in SCHED_BATCH made every 10 ms tick wait for the GIL (lateness p50
5 ms, p99 30 ms, against 0.06 / 0.13 ms without a recording); the writer keeping the process's
SCHED_FIFO gave p50 0.06 ms. So there a thread keeps the loop's class (``background`` leaves a
thread under SCHED_FIFO or SCHED_RR as it is, and ``runtime/rt_priority.py`` moves every thread of
the process, helpers included). Work that must give way to a real-time loop belongs in another
process (the operator's pages run in ``ui`` for this reason).
"""

from __future__ import annotations

import contextlib
import os
import threading

#: Policies a thread takes to say it must give way (``background``): never made real-time.
BACKGROUND_POLICIES = (os.SCHED_BATCH, os.SCHED_IDLE)


#: Real-time policies: a thread under one of them is in a real-time process, and keeps it.
REALTIME_POLICIES = (os.SCHED_FIFO, os.SCHED_RR)


def background(nice: int = 10) -> None:
    """Put the calling thread in the background: ``SCHED_BATCH`` at ``nice`` (a recorder, a
    video encoder), so that under CPU starvation it gives way first. A thread of a real-time
    process (it inherited SCHED_FIFO) keeps its class: it shares the loop's GIL (see the module
    docstring). Where the system refuses, it stays as it is."""
    tid = threading.get_native_id()
    with contextlib.suppress(AttributeError, OSError):
        if os.sched_getscheduler(tid) in REALTIME_POLICIES:
            return
    with contextlib.suppress(AttributeError, OSError):
        os.sched_setscheduler(tid, os.SCHED_BATCH, os.sched_param(0))
    with contextlib.suppress(AttributeError, OSError):
        os.setpriority(os.PRIO_PROCESS, tid, nice)
