"""Scheduler overhead and real-clock timing, each against a same-run baseline.

1. Dispatch overhead: a chain of 10 trivial modules for N ticks on the sim clock, against a plain
   Python loop calling the same step functions of the same wired modules. Goal < 3 µs per step.
2. Real-clock timing: one process at 1 kHz for S seconds against a bare ``time.sleep`` loop with
   absolute deadlines: period error p50/p99/max and the share of late periods (> 10 % of the
   period). Goal: p99 within 1.2x of the bare loop's.

    python benchmarks/bench_scheduler.py [--quick]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.common import percentiles, table, write_results
from umbra.connectors import Input, Module, Output
from umbra.connectors.messages import Scalar
from umbra.runtime.graph.check import check_text
from umbra.runtime.registry import Registry
from umbra.runtime.scheduler import Scheduler, SchedulerOptions


class Source(Module):
    """Sends one scalar per period."""

    out = Output(Scalar)

    def start(self) -> None:
        self._sample = Scalar(value=1.0)

    def step(self, now: float) -> None:
        self.out.send(self._sample)


class Pass(Module):
    """Forwards its input."""

    inp = Input(Scalar, trigger=True)
    out = Output(Scalar)

    def step(self, now: float) -> None:
        self.out.send(self.inp.value)


def chain_plan(n: int, rate: float):
    reg = Registry()
    reg.add(Source)
    reg.add(Pass)
    lines = ["graph: bench", "modules:", f"  m0: {{type: Source, rate: {rate}}}"]
    lines += [f"  m{i}: {{type: Pass}}" for i in range(1, n)]
    lines += ["connections:"] + [f"  - m{i - 1}.out -> m{i}.inp" for i in range(1, n)]
    return check_text("\n".join(lines), "bench.yaml", reg)


def dispatch(ticks: int, n: int = 10) -> dict[str, float]:
    plan = chain_plan(n, 1000.0)
    sched = Scheduler(plan, SchedulerOptions(clock="sim", max_ticks=ticks))
    for m in sched.modules.values():
        m.start()
    steps = [m.step for m in sched.modules.values()]
    t0 = time.perf_counter()
    for k in range(ticks):
        now = k * 1e-3
        for step in steps:
            step(now)
    plain = time.perf_counter() - t0
    sched2 = Scheduler(plan, SchedulerOptions(clock="sim", max_ticks=ticks))
    t0 = time.perf_counter()
    result = sched2.run()
    ours = time.perf_counter() - t0
    assert result.ticks == ticks and all(m.calls == ticks for m in result.modules)
    per_step_plain = plain / (ticks * n) * 1e6
    per_step_ours = ours / (ticks * n) * 1e6
    return {
        "ticks": ticks,
        "modules": n,
        "plain_loop_s": plain,
        "scheduler_s": ours,
        "plain_us_per_step": per_step_plain,
        "scheduler_us_per_step": per_step_ours,
        "overhead_us_per_step": per_step_ours - per_step_plain,
        "ratio": ours / plain,
    }


def bare_loop(rate: float, seconds: float) -> np.ndarray:
    period = 1.0 / rate
    n = int(seconds * rate)
    starts = np.empty(n)
    t0 = time.monotonic()
    for k in range(n):
        deadline = t0 + k * period
        delay = deadline - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        starts[k] = time.monotonic()
    return np.diff(starts)


class Stamp(Module):
    """Records the wall time of every step."""

    def start(self) -> None:
        self.times: list[float] = []

    def step(self, now: float) -> None:
        self.times.append(time.monotonic())


def our_loop(rate: float, seconds: float) -> tuple[np.ndarray, int]:
    reg = Registry()
    reg.add(Stamp)
    plan = check_text(f"graph: rt\nmodules:\n  s: {{type: Stamp, rate: {rate}}}\n", "rt.yaml", reg)
    sched = Scheduler(plan, SchedulerOptions(clock="real", duration=seconds))
    result = sched.run()
    return np.diff(np.asarray(sched.modules["s"].times)), result.modules[0].misses


def timing(rate: float, seconds: float) -> dict[str, dict[str, float]]:
    period = 1.0 / rate
    out = {}
    for name, periods, misses in (
        ("bare sleep loop", bare_loop(rate, seconds), 0),
        ("umbra scheduler", *our_loop(rate, seconds)),
    ):
        err = np.abs(periods - period)
        out[name] = {
            **{k: v * 1e3 for k, v in percentiles(err).items()},
            "late_share": float(np.mean(err > 0.1 * period)),
            "periods": int(periods.size),
            "misses": misses,
        }
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="shorter runs")
    args = parser.parse_args()
    ticks = 20_000 if args.quick else 100_000
    seconds = 2.0 if args.quick else 10.0
    d = dispatch(ticks)
    print(f"\nDispatch: chain of {d['modules']} modules, {ticks} ticks, sim clock")
    print(
        table(
            [
                ["plain Python loop", d["plain_us_per_step"], 1.0],
                ["umbra scheduler", d["scheduler_us_per_step"], d["ratio"]],
            ],
            ["", "µs per step", "ratio"],
        )
    )
    print(f"overhead per step: {d['overhead_us_per_step']:.3f} µs (goal < 3 µs)")
    t = timing(1000.0, seconds)
    print(f"\nReal clock: 1 kHz for {seconds:g} s, period error (ms)")
    rows = [[name, v["p50"], v["p99"], v["max"], v["late_share"]] for name, v in t.items()]
    print(table(rows, ["", "p50 ms", "p99 ms", "max ms", "late share"]))
    ratio = t["umbra scheduler"]["p99"] / max(t["bare sleep loop"]["p99"], 1e-9)
    print(f"p99 ratio umbra / bare: {ratio:.2f} (goal <= 1.2)")
    path = write_results(
        "scheduler",
        {"dispatch": d, "real_clock_1khz": t, "p99_ratio": ratio, "goals": {"p99_ratio_max": 1.2}},
        quick=args.quick,
    )
    print(f"\nwrote {path}")


if __name__ == "__main__":
    main()
