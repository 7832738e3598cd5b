"""Faults a trial makes from outside the graph: CPU overload with an operator's page open, and a
vision process stopped and continued (``--fault overload``, ``--fault vision_lag``).

Both test freshness: under either, every trial must grasp or stop safely, and the true tool may
travel at most ``MAX_STALE_TRAVEL_MM`` while the servo side's newest data is older than its bound.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from types import TracebackType

#: The most the true tool may travel while the guard's data is older than its bound [mm].
MAX_STALE_TRAVEL_MM = 5.0
#: Busy processes per CPU core under ``--fault overload`` (4: a load of four times the cores).
OVERLOAD_FACTOR = 4
#: How long ``--fault vision_lag`` keeps the vision process stopped (SIGSTOP), split [s]; in one
#: process the camera delivers frames this old for ``VISION_LAG_WINDOW_S`` instead.
VISION_LAG_S = 2.0
VISION_LAG_WINDOW_S = 3.0
#: Debian's Chromium, for the operator's page opened during an overload.
CHROMIUM = "/usr/bin/chromium"
CHROMIUM_FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
)
_BUSY = "while True: pass"


class Overload:
    """``factor`` busy processes per core for as long as it is entered, and (``page(url)``) a
    real Chromium showing the operator's page: what a busy operator's machine does to a run."""

    def __init__(self, factor: int = OVERLOAD_FACTOR) -> None:
        self.count = factor * (os.cpu_count() or 1)
        self._busy: list[subprocess.Popen[bytes]] = []
        self._browser: subprocess.Popen[bytes] | None = None
        self._profile: str | None = None

    def __enter__(self) -> Overload:
        self._busy = [
            subprocess.Popen([sys.executable, "-c", _BUSY], stdin=subprocess.DEVNULL)
            for _ in range(self.count)
        ]
        return self

    def page(self, url: str) -> bool:
        """Open ``url`` in headless Chromium (False when there is none on this machine)."""
        if self._browser is not None or not shutil.which(CHROMIUM):
            return False
        self._profile = tempfile.mkdtemp(prefix="umbra-overload-page-")
        self._browser = subprocess.Popen(
            [CHROMIUM, *CHROMIUM_FLAGS, f"--user-data-dir={self._profile}", url],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            stdin=subprocess.DEVNULL,
        )
        return True

    def __exit__(
        self,
        kind: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        for proc in [*self._busy, *([self._browser] if self._browser else [])]:
            proc.kill()
            proc.wait()
        if self._profile is not None:
            shutil.rmtree(self._profile, ignore_errors=True)


def stop_and_continue(process: subprocess.Popen[str], stopped_s: float = VISION_LAG_S) -> None:
    """SIGSTOP ``process`` for ``stopped_s`` seconds, then SIGCONT it (a process that lost its
    CPU for that long, or was suspended by hand)."""
    process.send_signal(signal.SIGSTOP)
    try:
        time.sleep(stopped_s)
    finally:
        process.send_signal(signal.SIGCONT)
