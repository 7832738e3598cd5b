"""Shared-memory segments of a process that died: found while it lives, removed once it is dead.

A process killed with SIGKILL cannot remove its ``/dev/shm`` files: this project's frame pools and
host marker (named after the pid, ``umbra.runtime.links.pool``) and zenoh's own shared-memory
segments (``/dev/shm/<number>.zenoh``, named without a pid). The launcher notes the segments each
child has mapped while it runs (``mapped_segments``) and, as soon as the child has ended, removes
those no living process maps any more (``remove_orphans``) — at once, not at the next start.
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path

from umbra.runtime.links.pool import SHM_DIR, sweep_stale


def mapped_segments(pid: int) -> set[str]:
    """Paths of the ``/dev/shm`` files process ``pid`` maps now (empty when it is gone)."""
    found: set[str] = set()
    prefix = f"{SHM_DIR}/"
    try:
        with open(f"/proc/{pid}/maps") as maps:
            for line in maps:
                at = line.find(prefix)
                if at >= 0:
                    found.add(line[at:].rstrip("\n").removesuffix(" (deleted)"))
    except OSError:
        pass
    return found


def _mapped_by_anyone(paths: set[str]) -> set[str]:
    """Those of ``paths`` some living process maps."""
    used: set[str] = set()
    with contextlib.suppress(OSError):
        for entry in os.scandir("/proc"):
            if entry.name.isdigit():
                used |= mapped_segments(int(entry.name)) & paths
                if used == paths:
                    break
    return used


def remove_orphans(paths: set[str]) -> int:
    """Remove the files of ``paths`` (segments of a dead process) no living process maps, and
    every pool or marker file of a dead process; the number of files removed."""
    removed = sweep_stale()
    for path in paths - _mapped_by_anyone(paths):
        with contextlib.suppress(OSError):
            Path(path).unlink()
            removed += 1
    return removed
