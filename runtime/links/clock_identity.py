"""Which ``CLOCK_MONOTONIC`` a process reads: its kernel's boot and its time namespace.

Two processes whose identities are equal read the same monotonic clock (Linux gives every process
of one boot the same ``CLOCK_MONOTONIC``, shifted only by a time namespace's offset), so the offset
between them is zero by construction and needs no measurement. Any other pair — another host, a
time namespace (``unshare --time``), or a kernel that does not say — is measured
(``umbra.runtime.links.clock_sync``).
"""

from __future__ import annotations

import os
from pathlib import Path

BOOT_ID = Path("/proc/sys/kernel/random/boot_id")
TIME_NAMESPACE = "/proc/self/ns/time"


def clock_identity() -> str:
    """``<boot id>/<time namespace>`` of this process; empty when either cannot be read (then no
    other process is taken to share our clock)."""
    try:
        boot = BOOT_ID.read_text().strip()
        namespace = os.readlink(TIME_NAMESPACE)
    except OSError:
        return ""
    if not boot or not namespace:
        return ""
    return f"{boot}/{namespace}"


def same_clock(ours: str, theirs: str) -> bool:
    """Whether two identities name one clock (an unknown identity names none)."""
    return bool(ours) and ours == theirs
