"""Benchmark: what recording costs a split pick-up, how big it is, and how fast replay reads it.

Rows, all measured in this run on the same machine:

* ``split pick-up``: ``umbra run graphs/tool_pickup.yaml`` over two processes on the real clock,
  alternately without and with ``--record`` (JPEG images, the default), ``--rounds`` pairs. Per
  mode: the servo process's tick lateness p99 (``summary-smart.json``; the median over rounds)
  and the vision frame time (mean step time of DigiCam + vsSnake + vsServo, ``summary-umbra.json``);
  the recording's bytes per second of run.
* ``reading`` the recording of the last round, and a sim recording with raw images, each way
  timed in wall and CPU seconds (all threads of this process; the CPU figure is the one a loaded
  machine disturbs least): ``mcap``'s plain reader (every record, no decoding: the baseline);
  ``umbra``'s reader (every record, CRCs checked); every sample of every channel decoded; the
  **replay feed**: ``umbra replay`` of the camera (images JPEG-decoded, truth contours) into light
  consumers (a ``Printer`` per output, nothing else: reading, decoding and handing over, the
  median of ``--feed-repeats``); the **replay with the full pick-up re-run**: the camera replayed
  into the pick-up graph on the sim clock (vision, servo, arm and world re-run), and the same
  without the graph's video writer, plot and operator page, beside that lean graph run live
  (camera rendered). Speed is recorded seconds per wall (or CPU) second.

Run: ``python benchmarks/bench_record.py [--quick]``; writes benchmarks/results/record.json.
Goals: recording changes the servo tick lateness p99 by at most 10 %; replay at least 20 x real
time on the sim clock.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.common import table, write_results  # noqa: E402
from umbra.connectors import safe_yaml  # noqa: E402

VISION = ("DigiCam", "vsSnake", "vsServo")
LATENESS_GOAL = 0.10
#: Module types left out of the graph replay re-runs for speed (they write files or serve a page).
LEAN_DROP = ("Overlay", "StatusPlot", "OperatorConsole")
REPLAY_GOAL = 20.0
FEED = "replay feed: camera into light consumers (sim)"
FULL = "replay with the full pick-up re-run (sim)"


def run_split(graph: Path, out: Path, duration: float, record: bool) -> dict[str, float]:
    """One split run; the servo lateness p99 [ms], vision frame time [ms], recording size."""
    cmd = [
        sys.executable,
        "-m",
        "umbra.runtime.cli.main",
        "run",
        str(graph),
        "--duration",
        str(duration),
    ]
    cmd += ["--out", str(out), "--quiet"] + (["--record"] if record else [])
    subprocess.run(cmd, cwd=ROOT, capture_output=True, timeout=duration + 120, check=False)
    smart = json.loads((out / "summary-smart.json").read_text())
    umbra = json.loads((out / "summary-umbra.json").read_text())
    vision_us = sum(m["mean_step_us"] for m in umbra["modules"] if m["type"] in VISION)
    rec = out / "recording.mcap"
    return {
        "lateness_p99_ms": float(smart["lateness_p99_ms"]),
        "lateness_p50_ms": float(smart["lateness_p50_ms"]),
        "vision_frame_ms": vision_us / 1000.0,
        "bytes": rec.stat().st_size if rec.exists() else 0,
        "seconds": duration,
    }


def lean_graph(graph: Path, out: Path) -> Path:
    """``graph`` without its video writer, plot and operator page (the operator's click goes
    straight to the snake): what re-running vsSnake and vsServo on a recording needs."""
    import re

    import yaml

    doc = safe_yaml.load(graph.read_text(), str(graph))[1]
    drop = {n for n, m in doc["modules"].items() if m["type"] in LEAN_DROP}
    for name in drop:
        del doc["modules"][name]
    keep = []
    for conn in doc["connections"]:
        src, _arrow, dst = re.split(r"\s*(->|~>)\s*", conn.strip())
        if src.split(".")[0] not in drop and dst.split(".")[0] not in drop:
            keep.append(conn)
    if {"operator", "snake"} <= set(doc["modules"]) and "operator.seed -> snake.seed" not in keep:
        keep.append("operator.seed -> snake.seed")
    doc["connections"] = keep
    path = out / "lean.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def feed_graph(graph: Path, out: Path) -> Path:
    """The cameras of ``graph`` (same parameters, so a recording of ``graph`` replays into it)
    with a light consumer on each connected output: a ``Printer`` at most one line a minute."""
    import yaml

    doc = safe_yaml.load(graph.read_text(), str(graph))[1]
    cameras = {n: m for n, m in doc["modules"].items() if m["type"] == "DigiCam"}
    modules: dict[str, object] = {  # one process
        n: {k: v for k, v in m.items() if k != "process"} for n, m in cameras.items()
    }
    connections = []
    for conn in doc["connections"]:
        src = conn.split("->")[0].split("~>")[0].strip()
        module, port = src.split(".")
        name = f"{module}_{port}_sink"
        if module in cameras and name not in modules:
            modules[name] = {"type": "Printer", "params": {"max_rate_hz": 1 / 60}}
            connections.append(f"{src} -> {name}.value")
    feed = {key: doc[key] for key in ("graph", "seed", "frames") if key in doc} | {
        "clock": "sim",
        "modules": modules,
        "connections": connections,
    }
    path = out / "feed.yaml"
    path.write_text(yaml.safe_dump(feed, sort_keys=False))
    return path


def _timed(fn: Callable[[], object]) -> tuple[float, float]:
    """(wall, CPU) seconds of ``fn()``; CPU of every thread of this process."""
    wall, cpu = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - wall, time.process_time() - cpu


def time_reads(
    path: Path, graph: Path, tmp: Path, repeats: int
) -> tuple[dict[str, tuple[float, float]], float]:
    """(wall, CPU) seconds of each way of reading ``path``, and its recorded duration [s]."""
    from mcap.reader import make_reader

    from umbra.runtime.graph.check import load_graph
    from umbra.runtime.recording.reader import read_records
    from umbra.runtime.recording.replay import plan_replay
    from umbra.runtime.recording.samples import iter_samples_parallel
    from umbra.runtime.run import run_process
    from umbra.runtime.scheduler import SchedulerOptions

    tmp.mkdir(parents=True, exist_ok=True)
    with open(path, "rb") as f:
        times = [m.log_time for _s, _c, m in make_reader(f).iter_messages(log_time_order=False)]
    recorded = (max(times) - min(times)) / 1e9

    def plain() -> None:
        with open(path, "rb") as f:
            assert sum(1 for _ in make_reader(f).iter_messages(log_time_order=False)) == len(times)

    def replay(graph_file: Path, out: Path) -> Callable[[], object]:
        def run() -> None:
            plan = load_graph(graph_file)
            plan_replay(plan, path, None, "sim")
            result = run_process(plan, SchedulerOptions(clock="sim", output_dir=out))
            assert result.ticks > 0 and result.exit_code in (0, 1), result.reason

        return run

    def median(fn: Callable[[], object]) -> tuple[float, float]:
        runs = sorted((_timed(fn) for _ in range(repeats)), key=lambda wc: wc[0])
        return runs[len(runs) // 2]

    spent: dict[str, tuple[float, float]] = {}
    spent["mcap plain reader (baseline)"] = median(plain)
    spent["umbra reader (every record, CRCs checked)"] = _timed(
        lambda: sum(1 for _ in read_records(path))
    )
    spent["every sample of every channel decoded"] = _timed(
        lambda: sum(1 for _ in iter_samples_parallel(path))
    )
    spent[FEED] = median(replay(feed_graph(graph, tmp), tmp / "feed"))
    spent[FULL] = _timed(replay(graph, tmp / "replay"))
    lean = lean_graph(graph, tmp)
    spent["live pick-up, no video/page (sim, camera rendered)"] = _timed(
        lambda: run_process(
            load_graph(lean),
            SchedulerOptions(clock="sim", duration=recorded, output_dir=tmp / "lean_live"),
        )
    )
    spent["replay into it (camera replayed)"] = _timed(replay(lean, tmp / "lean"))
    return spent, recorded


def raw_recording(graph: Path, out: Path, duration: float) -> Path:
    """The pick-up in one process on the sim clock, recorded with raw images."""
    cmd = [sys.executable, "-m", "umbra.runtime.cli.main", "run", str(graph), "--single-process"]
    cmd += ["--clock", "sim", "--duration", str(duration), "--record", "--record-images", "raw"]
    cmd += ["--out", str(out), "--quiet"]
    subprocess.run(cmd, cwd=ROOT, capture_output=True, check=False)
    return out / "recording.mcap"


def read_table(spent: dict[str, tuple[float, float]], recorded: float) -> list[list[object]]:
    base = spent["mcap plain reader (baseline)"][0]
    return [
        [name, wall, cpu, recorded / wall, recorded / cpu, wall / base]
        for name, (wall, cpu) in spent.items()
    ]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="one short round (smoke test)")
    parser.add_argument("--graph", type=Path, default=ROOT / "graphs" / "tool_pickup.yaml")
    parser.add_argument("--rounds", type=int, default=3, help="pairs of runs (off, on)")
    parser.add_argument("--duration", type=float, default=12.0, help="seconds per run")
    parser.add_argument(
        "--feed-repeats", type=int, default=3, help="replay-feed and baseline runs (median)"
    )
    args = parser.parse_args()
    rounds, duration = (1, 5.0) if args.quick else (args.rounds, args.duration)
    runs: dict[str, list[dict[str, float]]] = {"off": [], "on": []}
    with tempfile.TemporaryDirectory(prefix="bench_record_") as tmpdir:
        tmp = Path(tmpdir)
        for r in range(rounds):
            for mode in ("off", "on"):
                out = tmp / f"{mode}{r}"
                runs[mode].append(run_split(args.graph, out, duration, mode == "on"))
                print(f"round {r + 1}/{rounds} record {mode}: {runs[mode][-1]}", file=sys.stderr)
        last = tmp / f"on{rounds - 1}" / "recording.mcap"
        spent, recorded = time_reads(last, args.graph, tmp / "jpeg_reads", args.feed_repeats)
        raw = raw_recording(args.graph, tmp / "raw", 2.0 if args.quick else 6.0)
        raw_mb = raw.stat().st_size / 1e6
        raw_spent, raw_recorded = time_reads(raw, args.graph, tmp / "raw_reads", args.feed_repeats)

    def med(mode: str, key: str) -> float:
        return statistics.median(x[key] for x in runs[mode])

    p99_off, p99_on = med("off", "lateness_p99_ms"), med("on", "lateness_p99_ms")
    change = (p99_on - p99_off) / p99_off if p99_off > 0 else 0.0
    mb_per_s = med("on", "bytes") / duration / 1e6
    rows = [
        [
            "without --record (baseline)",
            med("off", "lateness_p50_ms"),
            p99_off,
            med("off", "vision_frame_ms"),
            "",
        ],
        [
            "with --record (JPEG images)",
            med("on", "lateness_p50_ms"),
            p99_on,
            med("on", "vision_frame_ms"),
            mb_per_s,
        ],
    ]
    print(f"split pick-up, {rounds} x ({duration:g} s without, {duration:g} s with), real clock")
    header = ["run", "servo lateness p50 ms", "p99 ms", "vision frame ms", "recording MB/s"]
    print(table(rows, header))
    print(f"lateness p99 change with recording: {change:+.1%} (goal within {LATENESS_GOAL:.0%})")
    header = ["reader", "wall s", "CPU s", "x real time", "x real time (CPU)", "x baseline wall"]
    print(f"\nreading the {recorded:.2f} s recording (JPEG images) of the last round")
    print(table(read_table(spent, recorded), header))
    print(f"\nreading a {raw_recorded:.2f} s sim recording with raw images ({raw_mb:.0f} MB)")
    print(table(read_table(raw_spent, raw_recorded), header))

    def speed(table_: dict[str, tuple[float, float]], name: str, span: float) -> float:
        return span / table_[name][0]

    base = speed(spent, "mcap plain reader (baseline)", recorded)
    feed, raw_feed = speed(spent, FEED, recorded), speed(raw_spent, FEED, raw_recorded)
    full, raw_full = speed(spent, FULL, recorded), speed(raw_spent, FULL, raw_recorded)
    lean_replay = speed(spent, "replay into it (camera replayed)", recorded)
    lean_live = speed(spent, "live pick-up, no video/page (sim, camera rendered)", recorded)
    print(
        f"\nreplay feed (JPEG): {feed:.1f} x real time ({recorded / spent[FEED][1]:.1f} x per "
        f"CPU second), mcap's plain reader {base:.1f} x; raw images {raw_feed:.1f} x; "
        f"goal {REPLAY_GOAL:g} x"
    )
    print(
        f"replay with the full pick-up re-run: {full:.1f} x real time (raw images {raw_full:.1f} "
        f"x); without video writer and page: {lean_replay:.1f} x (that graph live, camera "
        f"rendered: {lean_live:.1f} x)"
    )
    path = write_results(
        "record",
        {
            "graph": str(args.graph.relative_to(ROOT)) if args.graph.is_relative_to(ROOT) else "",
            "rounds": rounds,
            "duration_s": duration,
            "runs": runs,
            "lateness_p99_change": change,
            "recording_mb_per_s": mb_per_s,
            "recorded_s": recorded,
            "read_wall_cpu_s": spent,
            "mcap_plain_reader_x_real_time": base,
            "replay_feed_x_real_time": feed,
            "replay_full_pickup_x_real_time": full,
            "lean_replay_x_real_time": lean_replay,
            "lean_live_x_real_time": lean_live,
            "raw": {
                "recorded_s": raw_recorded,
                "mb": raw_mb,
                "read_wall_cpu_s": raw_spent,
                "replay_feed_x_real_time": raw_feed,
                "replay_full_pickup_x_real_time": raw_full,
            },
            "goals": {"lateness_p99_change_max": LATENESS_GOAL, "replay_x_min": REPLAY_GOAL},
        },
        quick=args.quick,
    )
    print(f"\nwrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
