"""The console on its real web server, stepped as its scheduler would (100 Hz, one thread), with
a test operator's page holding control, and floods started beside it (their own process)."""

from __future__ import annotations

import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from tests.operator.helpers import Page
from tests.poll import wait_for
from umbra.modules.operator.console import OperatorConsole
from umbra.runtime.harness import ModuleHarness

REPO = Path(__file__).resolve().parents[2]
T_TOOL_CAMERA = np.eye(4)
T_TOOL_CAMERA[:3, 3] = [0.0, 0.0, -0.12]


class Rig(threading.Thread):
    """Steps the console every 10 ms; records the wall time (monotonic s) of each command it
    sends on ``operator``."""

    def __init__(self, h: ModuleHarness) -> None:
        super().__init__(daemon=True)
        self.h = h
        self.sent_at: list[tuple[str, float]] = []
        self._halt = threading.Event()
        self.lock = threading.Lock()

    def run(self) -> None:
        seen = 0
        next_tick = time.monotonic()
        while not self._halt.is_set():
            with self.lock:
                self.h.step(dt=0.01)
                outs = self.h.outputs("operator")
            now = time.monotonic()
            for out in outs[seen:]:
                self.sent_at.append((str(out.action), now))  # a GrabCommand
            seen = len(outs)
            next_tick += 0.01
            time.sleep(max(0.0, next_tick - time.monotonic()))

    def wait(self, cond, timeout: float = 5.0, what: str = "") -> None:
        """Until ``cond()`` holds (looked at under the stepper's lock); ``timeout`` [s] at most."""

        def held() -> bool:
            with self.lock:
                return bool(cond())

        wait_for(held, timeout, what, 0.005)

    def operator(self) -> Page:
        """A page that joined and took control."""
        page = Page(self.h.module.url)
        self.wait(lambda: page.session in self.h.module.arbiter.sessions, 5.0, "the page joined")
        page.send("take")
        self.wait(lambda: self.h.module.arbiter.holder == page.session, 5.0, "the page in control")
        return page

    def abort_latency(self, page: Page) -> float:
        """Seconds from the page sending abort to the console sending it on ``operator``."""
        before = len(self.sent_at)
        t0 = time.monotonic()
        page.send("action", action="abort")
        end = t0 + 5.0
        while time.monotonic() < end:
            if len(self.sent_at) > before:
                action, at = self.sent_at[before]
                assert action == "abort"
                return at - t0
            time.sleep(0.001)
        raise AssertionError("the abort did not land within 5 s")

    def stop(self) -> None:
        self._halt.set()
        self.join(5)


@contextmanager
def console_rig() -> Iterator[Rig]:
    with ModuleHarness(OperatorConsole, {}, frames={"tool->camera": T_TOOL_CAMERA}) as h:
        rig = Rig(h)
        rig.start()
        try:
            yield rig
        finally:
            rig.stop()


@contextmanager
def flood(kind: str, url: str, seconds: float, wait: bool = True) -> Iterator[subprocess.Popen]:
    """``tests/security/flood.py`` as its own process for ``seconds`` (from when it says it
    floods; then 0.5 s more for its first connections); at the end, waits for it to finish
    (``wait``) or stops it."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "tests.security.flood", kind, url, str(seconds)],
        cwd=REPO,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout is not None and proc.stdout.readline().strip() == "flooding"
        time.sleep(0.5)
        yield proc
    finally:
        if not wait:
            proc.terminate()
        try:
            proc.wait(seconds + 20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(5)
