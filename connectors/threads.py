"""Threads a module starts for work that must give way: a video encoder, a recording writer.

A module's device readers and encoders run beside the scheduler's loop. Work whose only cost of
falling behind is a dropped or late frame in a file (never the freshness of the control path)
gives way under CPU starvation, in one of two ways:

* :func:`background`: heavy work that holds the GIL rarely (a video encoder, whose time is in
  OpenCV with the GIL released) goes under ``SCHED_BATCH``, and a process's ``realtime_priority``
  leaves it there (see ``runtime/rt_priority.py``);
* :func:`lowered`: light work that holds the GIL often (a recording's writer: a few Python
  calls per sample) is only niced. In an ordinary process that makes it give way; in a
  real-time one it follows the loop into ``SCHED_FIFO``. A thread that holds the GIL must never
  wait for a CPU while the loop waits for the GIL: under ``SCHED_BATCH`` on a loaded machine the
  writer was preempted holding it, and recording made the servo tick's lateness p99 30 ms
  instead of 0.2 ms (a priority inversion through the GIL).
"""

from __future__ import annotations

import contextlib
import os
import threading

#: Policies a thread takes to say it must give way (``background``): never made real-time.
BACKGROUND_POLICIES = (os.SCHED_BATCH, os.SCHED_IDLE)


def lowered(nice: int = 10) -> None:
    """Lower the calling thread's priority to ``nice`` without leaving its process's policy (see
    the module's docstring: light work that holds the GIL often). Where the system refuses, it
    stays as it is."""
    with contextlib.suppress(AttributeError, OSError):
        os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), nice)


def background(nice: int = 10) -> None:
    """Put the calling thread in the background: ``SCHED_BATCH`` at ``nice`` (a recorder, a
    video encoder), so that under CPU starvation it gives way first and a process's
    ``realtime_priority`` leaves it there. Where the system refuses, it stays as it is."""
    tid = threading.get_native_id()
    with contextlib.suppress(AttributeError, OSError):
        os.sched_setscheduler(tid, os.SCHED_BATCH, os.sched_param(0))
    with contextlib.suppress(AttributeError, OSError):
        os.setpriority(os.PRIO_PROCESS, tid, nice)
