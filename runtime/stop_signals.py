"""Ctrl-C, SIGTERM and Ctrl-Z stop a run safely: the loop ends after its tick, outputs are
zeroed (``umbra.runtime.safe_stop``) and every module stops. Ctrl-Z stops too, since a suspended
loop cannot watch the arm."""

from __future__ import annotations

import signal
import threading
from collections.abc import Callable
from typing import Any

from umbra.runtime.run_options import INTERRUPTED


def install_stop_signals(request_stop: Callable[[str, int], None]) -> dict[int, Any]:
    """Route SIGINT, SIGTERM and SIGTSTP to ``request_stop(reason, exit status)``; returns the
    handlers they replace (nothing off the main thread, where Python cannot set them)."""
    if threading.current_thread() is not threading.main_thread():
        return {}
    old: dict[int, Any] = {}

    def on_signal(signum: int, frame: Any) -> None:
        name = signal.Signals(signum).name
        if signum == signal.SIGTSTP:  # Ctrl-Z: a suspended loop cannot watch the arm
            request_stop("suspended by Ctrl-Z (SIGTSTP): stopped safely instead", INTERRUPTED)
        else:
            request_stop(f"interrupted by {name}", INTERRUPTED)

    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGTSTP):
        old[sig] = signal.signal(sig, on_signal)
    return old


def restore_signals(old: dict[int, Any]) -> None:
    """Put back the handlers ``install_stop_signals`` replaced."""
    for sig, handler in old.items():
        signal.signal(sig, handler)
