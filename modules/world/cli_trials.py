"""``umbra trials GRAPH -n N --seed S``: randomized tool pick-ups on the sim clock, with the
open-loop grab beside them, or failure-injection trials (``--fault``), in one process or split
over two (``--split``)."""

from __future__ import annotations

import argparse
import itertools
import json
import logging
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from umbra.connectors.cli_support import check_seconds, print_json
from umbra.connectors.errors import UserError
from umbra.connectors.json_text import json_text
from umbra.modules.world.trial_faults import MAX_STALE_TRAVEL_MM
from umbra.modules.world.trial_runner import TrialGraph, run_single, run_split
from umbra.modules.world.trials import (
    FAULTS,
    FRESHNESS_FAULTS,
    TrialResult,
    TrialSetup,
    aggregate,
    draw_trial,
)

NAME = "trials"
HELP = "randomized tool pick-up trials (success rate, errors, open-loop baseline, faults)"
GUIDE = "docs/guide/pickup.md"  # the guide page this command's --help points to


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("graph", metavar="GRAPH", help="a tool pick-up graph")
    parser.add_argument("-n", type=int, default=20, help="number of trials (default 20)")
    parser.add_argument(
        "--seed", type=int, default=0, help="seed of the randomization (default 0, at least 0)"
    )
    parser.add_argument(
        "--fault", choices=FAULTS, default="none", help="inject a fault mid-approach in every trial"
    )
    parser.add_argument(
        "--split",
        action="store_true",
        help="run each trial split over the graph's processes (real clock, zenoh)",
    )
    parser.add_argument("--workers", type=int, default=1, help="trials run in parallel")
    parser.add_argument(
        "--timeout",
        type=float,
        default=40.0,
        metavar="S",
        help="a trial without a grasp ends after S seconds of clock time",
    )
    parser.add_argument(
        "--out",
        type=Path,
        metavar="DIR",
        help="keep each trial's output here (default: a new temporary folder, named on stderr)",
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--only", metavar="A:B", help=argparse.SUPPRESS)  # a worker's share
    parser.add_argument("--jsonl", action="store_true", help=argparse.SUPPRESS)


def _one(
    graph: TrialGraph, setup: TrialSetup, split: bool, out: Path, timeout: float
) -> TrialResult:
    runner = run_split if split else run_single
    return runner(graph, setup, out / f"trial-{setup.index:04d}", timeout_s=timeout)


def _workers(args: argparse.Namespace, n: int, out: Path) -> list[dict[str, Any]]:
    """Run the trials in ``args.workers`` child processes (JSON over pipes, never pickle)."""
    bounds = np.linspace(0, n, args.workers + 1).astype(int)
    procs = []
    for a, b in itertools.pairwise(bounds):
        if b <= a:
            continue
        cmd = [
            sys.executable,
            "-m",
            "umbra.runtime.cli.main",
            "trials",
            args.graph,
            "-n",
            str(n),
            "--seed",
            str(args.seed),
            "--fault",
            args.fault,
            "--timeout",
            str(args.timeout),
            "--out",
            str(out),
            "--only",
            f"{a}:{b}",
            "--jsonl",
        ]
        if args.split:
            cmd.append("--split")
        procs.append(
            subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        )
    rows: list[dict[str, Any]] = []
    import selectors

    sel = selectors.DefaultSelector()
    for p in procs:
        sel.register(p.stdout, selectors.EVENT_READ)  # type: ignore[arg-type]
    open_streams = len(procs)
    while open_streams:
        for key, _ in sel.select():
            line = key.fileobj.readline()  # type: ignore[union-attr]
            if not line:
                sel.unregister(key.fileobj)
                open_streams -= 1
                continue
            rows.append(json.loads(line))
            _progress(len(rows), n, rows)
    for p in procs:
        p.wait()
    return sorted(rows, key=lambda r: r["setup"]["index"])


def _progress(done: int, n: int, rows: list[dict[str, Any]]) -> None:
    ok = sum(1 for r in rows if r["grasped"])
    width = 30
    filled = int(width * done / max(n, 1))
    sys.stderr.write(f"\r[{'#' * filled}{'.' * (width - filled)}] {done}/{n} trials, {ok} grasped")
    if done == n:
        sys.stderr.write("\n")
    sys.stderr.flush()


def _from_dict(row: dict[str, Any]) -> TrialResult:
    setup = TrialSetup(
        **{
            **row["setup"],
            "tool_xy_m": tuple(row["setup"]["tool_xy_m"]),
            "cast_rgb": tuple(row["setup"]["cast_rgb"]),
            "calibration_error_deg": tuple(row["setup"]["calibration_error_deg"]),
        }
    )
    return TrialResult(**{**row, "setup": setup})


def fault_figures(results: list[TrialResult]) -> dict[str, Any]:
    """Safety figures of failure-injection trials."""

    def stats(key: str) -> dict[str, float | None]:
        values = [r.safety[key] for r in results if key in r.safety]
        if not values:
            return {"median": None, "max": None}
        return {"median": float(np.median(values)), "max": float(np.max(values))}

    safe = [r for r in results if not r.grasped and r.safety.get("stopped") and r.assist_reason]
    if results and results[0].setup.fault in FRESHNESS_FAULTS:  # grasp or stop, never far on
        safe = [  # old data
            r
            for r in results
            if r.safety.get("travel_while_stale_mm", 0.0) <= MAX_STALE_TRAVEL_MM
            and (r.ended_unharmed or bool(r.assist_reason))
        ]
    return {
        "trials": len(results),
        "stopped_safely": len(safe),
        "stopped_safely_rate": len(safe) / len(results) if results else 0.0,
        "grasps": sum(r.grasped for r in results),
        "time_to_zero_command_s": stats("time_to_zero_command_s"),
        "time_to_standstill_s": stats("time_to_standstill_s"),
        "travel_after_fault_mm": stats("travel_after_fault_mm"),
        "travel_while_stale_mm": stats("travel_while_stale_mm"),
        "stale_episodes": sum(r.safety.get("stale_episodes", 0) for r in results),
        "reasons": sorted({r.assist_reason for r in results if r.assist_reason})[:10],
    }


def main(args: argparse.Namespace) -> int:
    for name, value, ok, expected in (
        ("-n", args.n, args.n >= 1, "at least 1"),
        ("--seed", args.seed, args.seed >= 0, "a non-negative integer"),
        ("--workers", args.workers, args.workers >= 1, "at least 1"),
    ):
        if not ok:
            raise UserError(f"{name}: expected {expected}, found {value}")
    check_seconds("--timeout", args.timeout)
    if args.fault == "kill_umbra" and not args.split:
        raise UserError("--fault kill_umbra kills the vision process: it needs --split")
    logging.basicConfig(level=logging.ERROR, format="%(levelname)s %(name)s: %(message)s")
    graph = TrialGraph(args.graph)
    out = args.out
    if out is None:
        out = Path(tempfile.mkdtemp(prefix="umbra-trials-"))
        print(f"umbra trials: each trial's output goes to {out} (--out to choose)", file=sys.stderr)
    first, last = 0, args.n
    if args.only:
        first, last = (int(v) for v in args.only.split(":"))
    started = time.monotonic()
    if args.workers > 1 and not args.only:
        rows = _workers(args, args.n, out)
        results = [_from_dict(r) for r in rows]
    else:
        results = []
        for index in range(first, last):
            setup = draw_trial(args.seed, index, fault=args.fault)
            result = _one(graph, setup, args.split, out, args.timeout)
            results.append(result)
            if args.jsonl:
                print(json_text(result.as_dict(), default=float), flush=True)
            else:
                _progress(len(results), last - first, [{"grasped": r.grasped} for r in results])
    if args.jsonl:
        return 0
    summary = aggregate(results)
    summary["wall_time_s"] = round(time.monotonic() - started, 1)
    summary["split"] = args.split
    if args.fault != "none":
        summary["fault"] = args.fault
        summary["safety"] = fault_figures(results)
    if args.json:
        print_json(summary)
    else:
        _print_table(summary, results)
    if args.fault != "none":
        return 0 if summary["safety"]["stopped_safely"] == len(results) else 1
    return 0


def _print_table(summary: dict[str, Any], results: list[TrialResult]) -> None:
    def f(d: dict[str, Any] | None, k: str, scale: float = 1.0) -> str:
        v = None if d is None else d.get(k)
        return "-" if v is None else f"{v * scale:.3g}"

    how = "split over the graph's processes" if summary["split"] else "one process, sim clock"
    print(f"{summary['trials']} trials ({how}), {summary['wall_time_s']} s")
    if "safety" not in summary:
        print(
            f"  visual servo : success {summary['success_rate']:.1%}; final error "
            f"{f(summary['final_error_mm'], 'median')} / {f(summary['final_error_mm'], 'p95')} / "
            f"{f(summary['final_error_mm'], 'max')} mm and "
            f"{f(summary['final_error_deg'], 'median')} / {f(summary['final_error_deg'], 'p95')} / "
            f"{f(summary['final_error_deg'], 'max')} deg (median / p95 / max); time "
            f"{f(summary['time_s'], 'median')} s median"
        )
        print(
            f"  open loop    : success {summary['open_loop_success_rate']:.1%}; error "
            f"{f(summary['open_loop_error_mm'], 'median')} / "
            f"{f(summary['open_loop_error_mm'], 'p95')} / "
            f"{f(summary['open_loop_error_mm'], 'max')} mm (median / p95 / max)"
        )
    else:
        s = summary["safety"]
        print(
            f"  fault {summary['fault']}: stopped safely {s['stopped_safely']}/{s['trials']}, "
            f"grasps {s['grasps']}; zero command after "
            f"{f(s['time_to_zero_command_s'], 'median', 1e3)} ms median "
            f"({f(s['time_to_zero_command_s'], 'max', 1e3)} max); standstill after "
            f"{f(s['time_to_standstill_s'], 'median', 1e3)} ms median; travel after the "
            f"fault {f(s['travel_after_fault_mm'], 'median')} mm median "
            f"({f(s['travel_after_fault_mm'], 'max')} max)"
        )
        print(
            f"  data older than the guard's bound: {s['stale_episodes']} times; the true tool "
            f"travelled {f(s['travel_while_stale_mm'], 'max')} mm at most meanwhile (limit "
            f"{MAX_STALE_TRAVEL_MM:g} mm)"
        )
        for reason in s["reasons"]:
            print(f"    reason: {reason}")
    misses = [r for r in results if not r.grasped and summary.get("fault") is None]
    for r in misses[:10]:
        print(f"  trial {r.setup.index}: {r.verdict}")
