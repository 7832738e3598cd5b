"""Threads a module starts for work that must give way: a video encoder, a recording writer.

A module's device readers and encoders run beside the scheduler's loop. Work whose only cost of
falling behind is a dropped or late frame in a file (never the freshness of the control path)
puts its thread in the background, so that under CPU starvation it gives way first, and a
process's ``realtime_priority`` leaves it there (see ``runtime/rt_priority.py``).
"""

from __future__ import annotations

import contextlib
import os
import threading

#: Policies a thread takes to say it must give way (``background``): never made real-time.
BACKGROUND_POLICIES = (os.SCHED_BATCH, os.SCHED_IDLE)


def background(nice: int = 10) -> None:
    """Put the calling thread in the background: ``SCHED_BATCH`` at ``nice`` (a recorder, a
    video encoder), so that under CPU starvation it gives way first and a process's
    ``realtime_priority`` leaves it there. Where the system refuses, it stays as it is."""
    tid = threading.get_native_id()
    with contextlib.suppress(AttributeError, OSError):
        os.sched_setscheduler(tid, os.SCHED_BATCH, os.sched_param(0))
    with contextlib.suppress(AttributeError, OSError):
        os.setpriority(os.PRIO_PROCESS, tid, nice)
