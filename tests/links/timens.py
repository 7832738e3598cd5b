"""Run a command in a new Linux time namespace whose CLOCK_MONOTONIC is ahead by a fraction of a
second (``unshare(1)`` takes whole seconds only): ``python timens.py SECONDS CMD...``.

``unshare(CLONE_NEWTIME)`` makes the namespace for this process's children; its offsets can be
written until a process enters it, and ``exec`` enters it. Root only.
"""

from __future__ import annotations

import ctypes
import os
import sys

CLONE_NEWTIME = 0x80


def main() -> None:
    ahead_s = float(sys.argv[1])
    libc = ctypes.CDLL(None, use_errno=True)
    if libc.unshare(CLONE_NEWTIME) != 0:
        raise SystemExit(f"unshare(CLONE_NEWTIME) failed: {os.strerror(ctypes.get_errno())}")
    whole = int(ahead_s // 1)
    nanos = round((ahead_s - whole) * 1e9)
    with open("/proc/self/timens_offsets", "w") as offsets:
        offsets.write(f"monotonic {whole} {nanos}\n")
    os.execvp(sys.argv[2], sys.argv[2:])


if __name__ == "__main__":
    main()
