"""CPU time of single threads (Linux ``/proc/self/task/<tid>/stat``), to tell the console's share
of its process. Seconds of user + system time."""

from __future__ import annotations

import os
import time

_TICK = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100


def thread_cpu_s(native_id: int) -> float:
    """User + system CPU seconds of thread ``native_id`` of this process (0.0 when gone)."""
    try:
        with open(f"/proc/self/task/{native_id}/stat", encoding="ascii") as f:
            fields = f.read().rsplit(")", 1)[1].split()
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / _TICK


def process_cpu_s() -> float:
    """User + system CPU seconds of this whole process (every thread)."""
    return time.process_time()
