"""Tool pick-up trial sets: randomized grabs against the open-loop baseline (same arm, same
calibration errors, measured in the same run), and failure injection in one process and split
over two processes.

    python benchmarks/bench_pickup.py [--quick] [--workers 2]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.common import table, write_results

GRAPH = str(Path(__file__).resolve().parent.parent / "graphs" / "tool_pickup.yaml")


def trials(*args: str) -> dict:
    cmd = [sys.executable, "-m", "umbra.runtime.cli.main", "trials", GRAPH, "--json", *args]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode not in (0, 1):
        raise SystemExit(f"trials failed ({proc.returncode}): {proc.stderr[-2000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def depth_offsets(out: Path) -> dict[str, float | int | None]:
    """Median and 5th/95th percentiles of the grasp's depth offset [mm] (the z of World's
    ``offset_patch_mm``, the tool point in the patch frame) over the grasped trials in ``out``."""
    values = []
    for summary in sorted(out.glob("**/summary*.json")):
        for module in json.loads(summary.read_text()).get("modules", []):
            if module.get("type") == "World" and module.get("grasped"):
                values.append(float(module["offset_patch_mm"][2]))
    if not values:
        return {"trials": 0, "median": None, "p5": None, "p95": None}
    return {
        "trials": len(values),
        "median": float(np.median(values)),
        "p5": float(np.percentile(values, 5)),
        "p95": float(np.percentile(values, 95)),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--seed", type=int, default=2026)
    args = parser.parse_args()
    n = 20 if args.quick else 200
    nf = 3 if args.quick else 10
    ns = 2 if args.quick else 3
    w = str(args.workers)
    results: dict[str, dict] = {}
    with tempfile.TemporaryDirectory() as out:
        results["randomized"] = trials(
            "-n", str(n), "--seed", str(args.seed), "--workers", w, "--out", out
        )
        r = results["randomized"]
        r["final_offset_z_mm"] = depth_offsets(Path(out))
    z = r["final_offset_z_mm"]
    if z["trials"]:
        print(
            f"final depth offset of the tool point along the patch normal: median"
            f" {z['median']:+.3f} mm, p5 {z['p5']:+.3f}, p95 {z['p95']:+.3f} ({z['trials']} grasps)"
        )
    print(f"\nRandomized pick-ups ({n} trials, sim clock)")
    print(
        table(
            [
                [
                    "visual servo",
                    r["success_rate"],
                    r["final_error_mm"]["median"],
                    r["final_error_mm"]["p95"],
                    r["final_error_mm"]["max"],
                    r["final_error_deg"]["p95"],
                    r["time_s"]["median"],
                ],
                [
                    "open loop (true tool pose)",
                    r["open_loop_success_rate"],
                    r["open_loop_error_mm"]["median"],
                    r["open_loop_error_mm"]["p95"],
                    r["open_loop_error_mm"]["max"],
                    "",
                    "",
                ],
            ],
            ["", "success", "err mm p50", "p95", "max", "deg p95", "time s p50"],
        )
    )
    rows = []
    for fault in ("occluder", "remove_patch", "distractor", "freeze"):
        for split in (False, True):
            count = ns if split else nf
            extra = ["--split"] if split else ["--workers", w]
            key = f"{fault}{' split' if split else ''}"
            results[key] = trials(
                "-n", str(count), "--seed", str(args.seed), "--fault", fault, *extra
            )
    results["kill_umbra split"] = trials(
        "-n", str(ns + 2), "--seed", str(args.seed), "--fault", "kill_umbra", "--split"
    )
    for key, value in results.items():
        if "safety" not in value:
            continue
        s = value["safety"]
        rows.append(
            [
                key,
                f"{s['stopped_safely']}/{s['trials']}",
                s["grasps"],
                _ms(s["time_to_zero_command_s"]["median"]),
                _ms(s["time_to_zero_command_s"]["max"]),
                _ms(s["time_to_standstill_s"]["max"]),
                s["travel_after_fault_mm"]["median"],
                s["travel_after_fault_mm"]["max"],
            ]
        )
    print("\nFailure injection (time from the fault; travel of the tool after the fault)")
    print(
        table(
            rows,
            [
                "fault",
                "stopped",
                "grasps",
                "zero cmd ms p50",
                "max",
                "standstill ms max",
                "travel mm p50",
                "max",
            ],
        )
    )
    path = write_results("pickup", {"seed": args.seed, **results}, quick=args.quick)
    print(f"\nwrote {path}")


def _ms(value: float | None) -> float | str:
    return "-" if value is None else value * 1e3


if __name__ == "__main__":
    main()
