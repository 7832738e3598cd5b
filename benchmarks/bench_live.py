"""Benchmark: a running pick-up served live to a Foxglove client (``umbra run --foxglove``).

Rows, all measured in this run on the same machine: ``graphs/tool_pickup.yaml`` in one process on
the real clock with its camera at 640 x 480, 30 fps (JPEG on the live connection), the joint
states at 100 Hz, alternately without a client and with Foxglove's own npm client
(``@foxglove/ws-protocol``, ``tests/live/node``) subscribed to the image and the joint states (as a
viewer with an image panel and a plot), or a stalled client, ``--rounds`` each, the live server on
in all.

- fps: images the client decoded per second of its window; joint states likewise;
- latency: sample stamp (the Foxglove message's own timestamp, wall clock) to the client's
  receipt (``performance.timeOrigin + performance.now()``), p50 and p95, images and joint states;
- servo side: tick lateness p50 and p99, median over rounds, and the ratio to the same layout
  without a client: in one process (``summary.json``: servo loop, vision and the live server share
  the process, the worst case) and in the graph's three processes (``summary-smart.json``: the
  servo side; the live server runs in the ``umbra`` command and observes on zenoh);
- a stalled client: subscribes to every channel, then never reads (a slow or hostile viewer).

Run: ``python benchmarks/bench_live.py [--quick]``; writes benchmarks/results/live.json.
Goals: >= 25 fps, image p95 <= 60 ms on loopback; lateness with a client within noise (ratio).
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.common import table, write_results  # noqa: E402

FPS_GOAL = 25.0
P95_GOAL_MS = 60.0
VGA = [
    "--set", "camera.width=640", "--set", "camera.height=480",
    "--set", "camera.u0=320", "--set", "camera.v0=240",
    "--set", "servo.u0=320", "--set", "servo.v0=240",
]  # fmt: skip
STREAM_KEYS = ("image_fps", "image_p50_ms", "image_p95_ms", "joints_fps", "joints_p50_ms")
STREAM_KEYS += ("joints_p95_ms",)
#: What the client subscribes to: a viewer with an image panel and the joints in a plot.
WATCHED = ("/camera/image", "/joints/joint_state")
_URL = re.compile(r"foxglove: open (ws://\S+)")


def install_client(folder: Path) -> Path:
    """The npm client, installed into ``folder`` (no global install)."""
    for name in ("package.json", "client.js"):
        shutil.copy(ROOT / "tests" / "live" / "node" / name, folder / name)
    subprocess.run(
        ["npm", "install", "--no-audit", "--no-fund", "--loglevel=error"],
        cwd=folder,
        check=True,
        timeout=300,
    )
    return folder / "client.js"


def stall(url: str, seconds: float) -> None:
    """A viewer that subscribes to every channel and then stops reading (a stalled or hostile
    client): the socket fills, and whatever the server holds for it is its own loss."""
    import websockets.sync.client as ws_client

    with ws_client.connect(
        url, subprotocols=["foxglove.websocket.v1"], max_size=None, max_queue=1
    ) as conn:
        deadline = time.monotonic() + 10
        channels: list[int] = []
        while not channels and time.monotonic() < deadline:
            msg = conn.recv(timeout=5)
            if isinstance(msg, str) and json.loads(msg).get("op") == "advertise":
                channels = [c["id"] for c in json.loads(msg)["channels"]]
        subs = [{"id": i, "channelId": c} for i, c in enumerate(channels)]
        conn.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
        time.sleep(seconds)  # never reads again


def one_run(
    graph: Path, out: Path, duration: float, client: Path | None, split: bool, stalled: bool
) -> dict[str, float]:
    """One pick-up; the servo lateness, and with a client its fps and latencies."""
    log_path = out.with_suffix(".log")
    cmd = [sys.executable, "-m", "umbra.runtime.cli.main", "run", str(graph)]
    cmd += [] if split else ["--single-process"]
    cmd += ["--clock", "real", "--duration", str(duration), "--out", str(out), "--quiet"]
    cmd += ["--foxglove", "--foxglove-port", "0", *VGA]
    found: dict[str, float] = {}
    with open(log_path, "w") as log:
        proc = subprocess.Popen(cmd, cwd=ROOT, stdout=log, stderr=subprocess.STDOUT)
        url = ""
        deadline = time.monotonic() + 60
        while not url and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.1)
            match = _URL.search(log_path.read_text(errors="replace"))
            url = match.group(1) if match else ""
        if stalled and url:
            lead = 6.0 if split else 1.0
            time.sleep(lead)
            stall(url, max(2.0, duration - 5.0 - lead))
        if client is not None and url:
            lead = 6.0 if split else 0.0  # the processes up, linked and observed
            time.sleep(lead)
            window = max(2.0, duration - 5.0 - lead)
            done = subprocess.run(
                ["node", str(client), url, str(window), "", ",".join(WATCHED)],
                capture_output=True,
                text=True,
                timeout=window + 60,
            )
            report = json.loads(done.stdout.strip().splitlines()[-1])
            found |= measure(report, "/camera/image", "image")
            found |= measure(report, "/joints/joint_state", "joints")
        proc.wait(timeout=duration + 120)
    # the servo side: the `smart` process of a split run, the one process otherwise
    summary = json.loads((out / ("summary-smart.json" if split else "summary.json")).read_text())
    found["lateness_p50_ms"] = float(summary["lateness_p50_ms"])
    found["lateness_p99_ms"] = float(summary["lateness_p99_ms"])
    return found


def measure(report: dict, topic: str, name: str) -> dict[str, float]:
    """Rate [1/s] over the client's receipts and stamp → receipt latency p50/p95 [ms]."""
    t = report["topics"].get(topic) or {}
    receipts = np.asarray(t.get("receiptMs", []), dtype=float)
    stamps = np.asarray([int(s) for s in t.get("stampNs", []) if s is not None], dtype=float)
    if receipts.size < 2 or stamps.size != receipts.size:
        return {f"{name}_fps": 0.0, f"{name}_p50_ms": float("nan"), f"{name}_p95_ms": float("nan")}
    latency = receipts - stamps / 1e6
    span = (receipts[-1] - receipts[0]) / 1000.0
    return {
        f"{name}_fps": (receipts.size - 1) / span if span > 0 else 0.0,
        f"{name}_p50_ms": float(np.percentile(latency, 50)),
        f"{name}_p95_ms": float(np.percentile(latency, 95)),
        f"{name}_count": float(receipts.size),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="one short round (smoke test)")
    parser.add_argument("--rounds", type=int, default=3, help="pairs of runs (no client, client)")
    parser.add_argument("--duration", type=float, default=18.0, help="seconds per run")
    args = parser.parse_args()
    rounds, duration = (1, 14.0) if args.quick else (args.rounds, args.duration)
    graph = ROOT / "graphs" / "tool_pickup.yaml"
    modes = ("off", "on", "stalled")
    runs: dict[str, dict[str, list[dict[str, float]]]] = {
        layout: {m: [] for m in modes} for layout in ("single", "split")
    }
    with tempfile.TemporaryDirectory(prefix="bench_live_") as tmpdir:
        tmp = Path(tmpdir)
        (tmp / "npm").mkdir()
        client = install_client(tmp / "npm")
        for layout in ("single", "split"):
            for r in range(rounds):
                for mode in modes:
                    out = tmp / f"{layout}-{mode}{r}"
                    found = one_run(
                        graph,
                        out,
                        duration,
                        client if mode == "on" else None,
                        split=layout == "split",
                        stalled=mode == "stalled",
                    )
                    runs[layout][mode].append(found)
                    print(f"{layout} round {r + 1}/{rounds} {mode}: {found}", file=sys.stderr)

    def med(layout: str, mode: str, key: str) -> float:
        values = [x[key] for x in runs[layout][mode] if key in x and np.isfinite(x[key])]
        return statistics.median(values) if values else float("nan")

    ratios = {}
    for layout, what in (("single", "one process"), ("split", "three processes: smart's")):
        print(
            f"\npick-up, {what} tick lateness, real clock, 640 x 480 at 30 fps, "
            f"{rounds} x {duration:g} s per row"
        )
        base50, base99 = (
            med(layout, "off", "lateness_p50_ms"),
            med(layout, "off", "lateness_p99_ms"),
        )
        rows = []
        for mode, name in (
            ("off", "no client (baseline)"),
            ("on", "npm client on image and joints"),
            ("stalled", "stalled client (subscribed to all, reads nothing)"),
        ):
            p50, p99 = med(layout, mode, "lateness_p50_ms"), med(layout, mode, "lateness_p99_ms")
            ratios[f"{layout}_{mode}_p99_ratio"] = p99 / base99 if base99 > 0 else float("nan")
            rows.append(
                [name, p50, p99, p50 / base50 if base50 > 0 else float("nan"), p99 / base99]
            )
        print(table(rows, ["run", "lateness p50 ms", "p99 ms", "x p50", "x p99"]))
        header = ["stream", "rate /s", "latency p50 ms", "p95 ms", "goal"]
        rows = [
            [
                "image 640x480 JPEG",
                med(layout, "on", "image_fps"),
                med(layout, "on", "image_p50_ms"),
                med(layout, "on", "image_p95_ms"),
                f">= {FPS_GOAL:g} fps, p95 <= {P95_GOAL_MS:g} ms",
            ],
            [
                "joint states (100 Hz)",
                med(layout, "on", "joints_fps"),
                med(layout, "on", "joints_p50_ms"),
                med(layout, "on", "joints_p95_ms"),
                "",
            ],
        ]
        print(table(rows, header))
    path = write_results(
        "live",
        {
            "graph": "graphs/tool_pickup.yaml (640 x 480), one process and split, real clock",
            "rounds": rounds,
            "duration_s": duration,
            "runs": runs,
            **{
                f"{layout}_{key}": med(layout, "on", key)
                for layout in ("single", "split")
                for key in STREAM_KEYS
            },
            **ratios,
            "goals": {"image_fps_min": FPS_GOAL, "image_p95_ms_max": P95_GOAL_MS},
        },
        quick=args.quick,
    )
    print(f"\nwrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
