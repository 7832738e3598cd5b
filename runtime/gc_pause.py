"""Garbage collection kept out of a real-time loop's way.

CPython's cyclic collector sometimes runs a full collection, which walks every tracked object of
the process: after importing zenoh, numpy, scipy and OpenCV that is some 100,000 objects and
20-50 ms on a small machine, long enough for a 100 Hz servo loop to miss several ticks at a
random moment. What the process made before its run (libraries, the graph, the modules) lives for
the whole run, so :class:`HeapFreeze` collects once before the run's clock starts and freezes it
(``gc.freeze``): later collections walk only what was made since, which takes microseconds.
Reference counting still frees everything at once; only cycles wait for the (now cheap) collector.
Objects that module ``start`` makes (after the clock started) are not frozen: a few thousand.

Module code imports its heavy libraries where it uses them (so ``umbra check`` and ``umbra --help``
load none of them); a real-time process imports them here, before its clock starts
(:data:`RUN_IMPORTS`), so no step pays an import and the freeze covers them.
"""

from __future__ import annotations

import gc
import importlib
import time
from typing import Any

#: Libraries that module steps import where they use them: imported before a real-time loop.
RUN_IMPORTS = (
    "scipy.spatial.transform",
    "scipy.linalg",
    "scipy.interpolate",
    "scipy.optimize",
    "cv2",
    "ruckig",
)


def import_run_libraries() -> None:
    """Import :data:`RUN_IMPORTS` (those installed) now, not in a step."""
    for name in RUN_IMPORTS:
        try:
            importlib.import_module(name)
        except ImportError:
            continue


class HeapFreeze:
    """Collect and freeze the heap at ``acquire`` (when ``enabled``), unfreeze at ``release``."""

    def __init__(self, enabled: bool) -> None:
        self.enabled = enabled
        self.frozen = 0
        self.collect_ms = 0.0

    def acquire(self) -> None:
        if not self.enabled:
            return
        import_run_libraries()
        started = time.perf_counter()
        gc.collect()
        gc.freeze()
        self.collect_ms = (time.perf_counter() - started) * 1e3
        self.frozen = gc.get_freeze_count()

    def release(self) -> None:
        if self.enabled:
            gc.unfreeze()

    def summary(self) -> dict[str, Any]:
        """For the run's summary: objects frozen and what the collection before the loop took."""
        return {"frozen_objects": self.frozen, "collect_ms": round(self.collect_ms, 3)}
