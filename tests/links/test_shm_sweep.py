"""Shared memory of a killed process: found while it lives, removed as soon as it is dead."""

from __future__ import annotations

import mmap
import os
import secrets
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from tests.poll import wait_for
from umbra.runtime.links.shm_sweep import mapped_segments, remove_orphans

HOLDER = """
import mmap, os, sys, time
fd = os.open(sys.argv[1], os.O_RDWR | os.O_CREAT, 0o600)
os.ftruncate(fd, 65536)
m = mmap.mmap(fd, 65536)
print("mapped", flush=True)
time.sleep(60)
"""


@pytest.mark.skipif(not Path("/dev/shm").is_dir(), reason="no /dev/shm on this host")
def test_segments_of_a_killed_process_are_removed_unless_someone_maps_them() -> None:
    tag = secrets.token_hex(6)
    theirs = f"/dev/shm/{tag}-theirs.zenoh"
    shared = f"/dev/shm/{tag}-shared.zenoh"
    holders = [
        subprocess.Popen([sys.executable, "-c", HOLDER, path], stdout=subprocess.PIPE, text=True)
        for path in (theirs, shared)
    ]
    mine = None
    try:
        for h in holders:
            assert h.stdout is not None and h.stdout.readline().strip() == "mapped"
        seen = mapped_segments(holders[0].pid) | mapped_segments(holders[1].pid)
        assert {theirs, shared} <= seen
        with open(shared, "r+b") as f:  # this process maps the shared one too
            mine = mmap.mmap(f.fileno(), 0)
        for h in holders:
            os.kill(h.pid, signal.SIGKILL)
            h.wait()
        wait_for(
            lambda: not any(os.path.exists(f"/proc/{h.pid}") for h in holders),
            5.0,
            "the killed holders gone from /proc",
        )
        remove_orphans({theirs, shared})
        assert not os.path.exists(theirs)  # nobody maps it any more: removed at once
        assert os.path.exists(shared)  # still mapped by a living process: kept
    finally:
        if mine is not None:
            mine.close()
        for h in holders:
            if h.poll() is None:
                h.kill()
        for path in (theirs, shared):
            if os.path.exists(path):
                os.unlink(path)
