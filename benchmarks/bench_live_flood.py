"""Benchmark: the servo loop of a pick-up served live while its live server is flooded.

``graphs/tool_pickup.yaml`` in one process on the real clock (``--single-process --foxglove``:
the servo loop, vision and the live server share the process and its GIL, the worst case), the
grasp's end of the run off, ``--duration`` seconds. Rows, ``--rounds`` each, in turn in the same
benchmark run:

- none: no flood (the baseline);
- burn: the flood's process spinning its threads without a connection (the CPU a flood costs
  the machine, not the server: the baseline a flood is compared with on a 2-core machine);
- elsewhere: the connection flood below against a live server in a process of its own: what
  a flood costs the machine (its sender, the kernel, a server), not the run's process;
- connections: ``tests/live/flood.py`` from its own loopback address, as fast as it can, for the
  run but its first and last seconds: TCP connections without the token left half-open (nothing
  sent, a request head that never ends), upgrades without the token, garbage.

Figures: the process's tick lateness p50/p99/max (``summary.json``) and the ratio of p99 to
each baseline, the drive watchdog's stops (the simulated joints: a command held past its watchdog),
connections the flood opened, the most descriptors the run's process held (``/proc``), and
whether a viewer with the token got data at the flood's end.

Run: ``python benchmarks/bench_live_flood.py [--quick]``; writes
benchmarks/results/live_flood.json. Goal: lateness p99 under the flood within noise of the burn
and elsewhere baselines, no watchdog stop, descriptors bounded by the door.
"""

from __future__ import annotations

import argparse
import ast
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.common import table, write_results  # noqa: E402
from tests.live.ports import viewer_gets  # noqa: E402

GRAPH = ROOT / "graphs" / "tool_pickup.yaml"
MODES = ("none", "burn", "elsewhere", "connections")
_URL = re.compile(r"foxglove: open ws://127\.0\.0\.1:(\d+)/(\S+)")
_SUMMARY = re.compile(r"foxglove: (\{.*\})")
#: Seconds of the run before the flood starts (the pick-up under way) and after it ends.
LEAD_S, TAIL_S = 3.0, 2.0


def _fds(pid: int) -> int:
    try:
        return len(os.listdir(f"/proc/{pid}/fd"))
    except OSError:
        return 0


def _burn(seconds: float) -> subprocess.Popen:
    """Two threads spinning for ``seconds`` in a process of their own (the flood's CPU)."""
    code = (
        "import threading,time\n"
        f"end=time.monotonic()+{seconds}\n"
        "def spin():\n"
        "    while time.monotonic()<end: sum(range(1000))\n"
        "ts=[threading.Thread(target=spin) for _ in range(2)]\n"
        "[t.start() for t in ts]; [t.join() for t in ts]\n"
    )
    return subprocess.Popen([sys.executable, "-c", code])


#: A live server in a process of its own (the target of the ``elsewhere`` flood): prints its port.
_SINK = """
import sys, time
from umbra.connectors.access.secret import resolve_token
from umbra.runtime.live.viewer_server import ViewerServer
class Nothing:
    def get(self, names): return []
    def set(self, viewer, changes): return [], []
door = ViewerServer(name="sink", host="127.0.0.1", port=0, token=resolve_token("", "sink"),
                    origins=[], parameters=Nothing())
print(door.port, flush=True)
time.sleep(float(sys.argv[1]))
"""


def _flood(port: int, seconds: float) -> subprocess.Popen:
    """``tests/live/flood.py`` against ``port`` for ``seconds``."""
    return subprocess.Popen(
        [sys.executable, "-m", "tests.live.flood", "127.0.0.1", str(port), str(seconds)],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        text=True,
    )


def one_run(out: Path, mode: str, duration: float) -> dict[str, Any]:
    """One pick-up with ``mode``'s load during its middle; the figures of the module docstring."""
    log_path = out.with_suffix(".log")
    cmd = [sys.executable, "-m", "umbra.runtime.cli.main", "run", str(GRAPH), "--single-process"]
    cmd += ["--clock", "real", "--duration", str(duration), "--out", str(out), "--quiet"]
    cmd += ["--foxglove", "--foxglove-port", "0", "--set", "world.end_run=false"]
    found: dict[str, Any] = {"mode": mode}
    with open(log_path, "w") as log:
        proc = subprocess.Popen(cmd, cwd=ROOT, stdout=log, stderr=subprocess.STDOUT)
        match = None
        deadline = time.monotonic() + 60
        while match is None and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.1)
            match = _URL.search(log_path.read_text(errors="replace"))
        if match is None:
            proc.kill()
            raise RuntimeError(f"no foxglove address:\n{log_path.read_text()[-2000:]}")
        port, query = int(match.group(1)), match.group(2)
        time.sleep(LEAD_S)
        seconds = max(2.0, duration - LEAD_S - TAIL_S - 1.0)
        load = sink = None
        if mode == "burn":
            load = _burn(seconds)
        elif mode == "connections":
            load = _flood(port, seconds)
        elif mode == "elsewhere":
            sink = subprocess.Popen(
                [sys.executable, "-c", _SINK, str(seconds + 30)],
                cwd=ROOT,
                stdout=subprocess.PIPE,
                text=True,
            )
            assert sink.stdout is not None
            load = _flood(int(sink.stdout.readline()), seconds)
        base, most = _fds(proc.pid), 0
        end = time.monotonic() + seconds
        while time.monotonic() < end and proc.poll() is None:
            most = max(most, _fds(proc.pid))
            time.sleep(0.02)
        found["viewer_at_end"] = viewer_gets(port, query, "/joints/joint_state")
        if load is not None:
            out_text, _ = load.communicate(timeout=60)
            if mode in ("connections", "elsewhere"):
                report = json.loads(out_text.strip().splitlines()[-1])
                found["flood_opened"] = report["opened"]
                found["flood_closed_at_once"] = report["closed_at_once"]
        if sink is not None:
            sink.kill()
            sink.wait()
        found["fds_added_max"] = most - base
        found["exit_code"] = proc.wait(timeout=duration + 120)
    summary = json.loads((out / "summary.json").read_text())
    found["lateness_p50_ms"] = float(summary["lateness_p50_ms"])
    found["lateness_p99_ms"] = float(summary["lateness_p99_ms"])
    found["lateness_max_ms"] = float(summary["lateness_max_ms"])
    joints = next(m for m in summary["modules"] if m["module"] == "joints")
    found["watchdog_stops"] = int(joints.get("drive_watchdog_stops", 0))
    text = log_path.read_text(errors="replace")
    live = _SUMMARY.findall(text)
    found["viewers_refused"] = ast.literal_eval(live[-1])["viewers_refused"] if live else None
    found["log_lines"] = text.count("\n")
    found["tracebacks"] = text.count("Traceback")
    return found


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="one round of short runs")
    parser.add_argument("--rounds", type=int, default=3, help="runs of each mode")
    parser.add_argument("--duration", type=float, default=20.0, help="seconds per run")
    args = parser.parse_args()
    rounds, duration = (1, 14.0) if args.quick else (args.rounds, args.duration)
    runs: dict[str, list[dict[str, Any]]] = {m: [] for m in MODES}
    with tempfile.TemporaryDirectory(prefix="bench_live_flood_") as tmpdir:
        for r in range(rounds):
            for mode in MODES:
                found = one_run(Path(tmpdir) / f"{mode}{r}", mode, duration)
                runs[mode].append(found)
                print(f"round {r + 1}/{rounds} {mode}: {found}", file=sys.stderr, flush=True)

    def med(mode: str, key: str) -> float:
        values = [float(x[key]) for x in runs[mode] if x.get(key) is not None]
        return statistics.median(values) if values else float("nan")

    base = med("none", "lateness_p99_ms")
    burn = med("burn", "lateness_p99_ms")
    away = med("elsewhere", "lateness_p99_ms")
    rows, ratios = [], {}
    for mode, name in (
        ("none", "no flood (baseline)"),
        ("burn", "the flood's CPU, no connection"),
        ("elsewhere", "the flood on another process's server"),
        ("connections", "connection flood without the token"),
    ):
        p99 = med(mode, "lateness_p99_ms")
        ratios[f"{mode}_p99_ratio"] = p99 / base if base > 0 else float("nan")
        ratios[f"{mode}_p99_ratio_to_burn"] = p99 / burn if burn > 0 else float("nan")
        ratios[f"{mode}_p99_ratio_to_elsewhere"] = p99 / away if away > 0 else float("nan")
        rows.append(
            [
                name,
                med(mode, "lateness_p50_ms"),
                p99,
                med(mode, "lateness_max_ms"),
                ratios[f"{mode}_p99_ratio"],
                ratios[f"{mode}_p99_ratio_to_burn"],
                ratios[f"{mode}_p99_ratio_to_elsewhere"],
                sum(x["watchdog_stops"] for x in runs[mode]),
                med(mode, "flood_opened") if mode in ("connections", "elsewhere") else "",
                med(mode, "fds_added_max"),
                ",".join(x["viewer_at_end"] for x in runs[mode]),
            ]
        )
    print(
        f"\npick-up in one process with --foxglove, real clock, {rounds} x {duration:g} s per row"
    )
    header = ["run", "lateness p50 ms", "p99 ms", "max ms", "x p99", "x (burn)", "x (elsewhere)"]
    header += ["watchdog stops", "connections", "fds added", "viewer at end"]
    print(table(rows, header))
    path = write_results(
        "live_flood",
        {
            "graph": "graphs/tool_pickup.yaml, --single-process --foxglove, real clock",
            "rounds": rounds,
            "duration_s": duration,
            "runs": runs,
            **ratios,
            "watchdog_stops": {m: sum(x["watchdog_stops"] for x in runs[m]) for m in MODES},
            "tracebacks": sum(x["tracebacks"] for m in MODES for x in runs[m]),
        },
        quick=args.quick,
    )
    print(f"\nwrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
