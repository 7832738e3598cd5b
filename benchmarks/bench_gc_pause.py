"""What a full garbage collection would cost a running loop, with and without the heap frozen.

The process holds what a pick-up process holds once its modules are built: the runtime, zenoh,
numpy, scipy and OpenCV, and every module of ``graphs/tool_pickup.yaml``, started. Baseline: a
full collection (``gc.collect()``) as CPython runs one now and then, walking every tracked object.
Measured: the same after :class:`umbra.runtime.gc_pause.HeapFreeze` froze the heap, as the scheduler
does on the real clock before its run starts, and a second pick-up was then built and run, so
that a whole graph's modules and what their ``start`` made stay unfrozen (more than a real run
leaves: an upper bound). Pause p50 / max over ``--repeats`` collections.

    python benchmarks/bench_gc_pause.py [--quick]
"""

from __future__ import annotations

import argparse
import gc
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.common import table, write_results  # noqa: E402

FROZEN = "full collection, heap frozen, a pick-up built after"


def built_pickup() -> object:
    """The pick-up's modules, built and started in this process (kept alive by the result)."""
    import zenoh  # noqa: F401 - what a linked process holds

    from umbra.runtime.graph.check import load_graph
    from umbra.runtime.scheduler import Scheduler, SchedulerOptions

    out = Path(tempfile.mkdtemp(prefix="bench_gc_"))
    plan = load_graph(ROOT / "graphs" / "tool_pickup.yaml")
    scheduler = Scheduler(plan, SchedulerOptions(clock="sim", duration=0.05, output_dir=out))
    scheduler.run()  # starts, runs a few ticks and stops every module: their imports are made
    return scheduler


def pauses(repeats: int) -> list[float]:
    """Wall time [ms] of ``repeats`` full collections."""
    found = []
    for _ in range(repeats):
        started = time.perf_counter()
        gc.collect()
        found.append((time.perf_counter() - started) * 1e3)
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer collections")
    parser.add_argument("--repeats", type=int, default=0, help="collections per row")
    args = parser.parse_args()
    repeats = args.repeats or (10 if args.quick else 50)
    from umbra.runtime.gc_pause import HeapFreeze

    keep = built_pickup()
    tracked = len(gc.get_objects())
    baseline = pauses(repeats)
    heap = HeapFreeze(enabled=True)
    heap.acquire()
    after = built_pickup()  # made after the freeze: walked by every collection
    frozen = pauses(repeats)
    heap.release()
    del keep, after
    rows = {
        "full collection, heap as built (baseline)": baseline,
        FROZEN: frozen,
    }
    stats = {
        name: {"p50_ms": float(np.median(v)), "max_ms": float(np.max(v))}
        for name, v in rows.items()
    }
    base = stats["full collection, heap as built (baseline)"]["p50_ms"]
    print(f"\n{tracked} tracked objects, {repeats} collections each")
    print(
        table(
            [[n, s["p50_ms"], s["max_ms"], s["p50_ms"] / base] for n, s in stats.items()],
            ["", "p50 ms", "max ms", "x baseline"],
        )
    )
    path = write_results(
        "gc_pause",
        {
            "tracked_objects": tracked,
            "frozen_objects": heap.frozen,
            "repeats": repeats,
            **stats,
            "frozen_p50_x_baseline": stats[FROZEN]["p50_ms"] / base,
        },
        quick=args.quick,
    )
    print(f"\nwrote {path}")


if __name__ == "__main__":
    main()
