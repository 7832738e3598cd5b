"""Cost of the live 3-D view: servo tick lateness with and without it, frames the browser gets.

One two-process graph runs three times in this benchmark run (same machine, same load):
a simulated 1280x720 wrist camera at 30 fps in `umbra`, a 100 Hz REG_VEL loop in `smart`, and

1. ``no view``: no View3D module (the same-run baseline);
2. ``view, nobody watching``: View3D in the graph, wired to the camera, no browser;
3. ``view, page WxH``: View3D and a real Chromium page (Debian's, via Playwright) showing it,
   at two page sizes (headless Chromium draws WebGL in software here: its cost grows with the
   page's pixels and competes for the same two cores as the servo process).

Figures: the `smart` process's tick lateness p99 (ratio against the baseline), the View3D
module's step time, the video frames it handed to viser, and the frames per second the browser
received (websocket messages carrying a video frame, counted in the page by Playwright).

    python benchmarks/bench_view3d.py [--quick] [--policy fifo|default]

The servo process runs under SCHED_FIFO priority 50 as the shipped graphs ask
(``--policy default``: the default policy, for comparison).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np

from benchmarks.common import (
    POLICIES,
    SIM_ARM_SMART,
    SIM_ARM_SMART_WIRES,
    start_graph,
    table,
    write_results,
)
from tests.browser import CHROMIUM, launch

#: a websocket message that carries a video frame names viser's image property
IMAGE_PROP = b"_image_data"

GRAPH = """
graph: bench_view3d
seed: 0
clock: real
processes: {{umbra: {{}}, smart: {smart}}}
frames:
  base->table: {{xyz: [0, 0, 0.25]}}
  flange->tool: {{xyz: [0, 0, 0.14]}}
  tool->camera: {{xyz: [0, 0, -0.12]}}
modules:
  camera:
    type: DigiCam
    process: umbra
    rate: 30
    params: {{source: sim, width: 1280, height: 720, fx: 800, fy: 800, u0: 640, v0: 360,
             noise_sigma: 2.0}}
{sim_arm}
{view}
connections:
{sim_arm_wires}
{wire}
"""
#: the phases with a page open, and its size (CSS px)
VIEWPORTS = {"view, page 1200x800": (1200, 800), "view, page 640x400": (640, 400)}
VIEW = "  view: {type: View3D, process: umbra, rate: 30, params: {port: 0, max_fps: 15}}"
WIRE = "  - camera.image -> view.wrist_image\n  - joints.joint_state -> view.joint_state"


def _graph(folder: Path, with_view: bool, policy: str) -> Path:
    path = folder / f"bench_view3d_{'view' if with_view else 'none'}_{policy}.yaml"
    path.write_text(
        GRAPH.format(
            view=VIEW if with_view else "",
            wire=WIRE if with_view else "",
            smart=POLICIES[policy],
            sim_arm=SIM_ARM_SMART,
            sim_arm_wires=SIM_ARM_SMART_WIRES,
        )
    )
    return path


def _watch(url: str, seconds: float, viewport: tuple[int, int]) -> dict[str, Any]:
    """Open the page and count the video frames it receives over its websocket."""
    from playwright.sync_api import sync_playwright

    counts = {"frames": 0, "bytes": 0}
    stamps: list[float] = []

    def on_websocket(ws) -> None:
        def on_frame(payload) -> None:
            data = payload if isinstance(payload, bytes) else str(payload or "").encode()
            counts["bytes"] += len(data)
            if IMAGE_PROP in data and len(data) > 1000:
                counts["frames"] += 1
                stamps.append(time.monotonic())

        ws.on("framereceived", on_frame)

    with sync_playwright() as p:
        browser = launch(p)
        page = browser.new_page(viewport={"width": viewport[0], "height": viewport[1]})
        page.on("websocket", on_websocket)
        page.goto(url)
        page.wait_for_timeout(3000)  # page built, first frames in
        start_frames, start = counts["frames"], time.monotonic()
        page.wait_for_timeout(int(1000 * seconds))
        frames = counts["frames"] - start_frames
        elapsed = time.monotonic() - start
        browser.close()
    return {
        "browser_fps": round(frames / elapsed, 2),
        "browser_mb_per_s": round(counts["bytes"] / 1e6 / (elapsed + 3.0), 3),
    }


def _summary(out: Path, process: str) -> dict[str, Any]:
    return json.loads((out / f"summary-{process}.json").read_text())


def run_phase(folder: Path, phase: str, duration: float, policy: str) -> dict[str, Any]:
    with_view = phase != "no view"
    folder.mkdir(parents=True, exist_ok=True)
    out = folder / phase.replace(" ", "_").replace(",", "")
    after = "3-D view: " if with_view else None
    proc, url = start_graph(_graph(folder, with_view, policy), out, duration, after)
    figures: dict[str, Any] = {}
    if phase in VIEWPORTS:
        figures.update(_watch(url, duration - 8.0, VIEWPORTS[phase]))
    proc.wait(duration + 60)
    umbra, smart = _summary(out, "umbra"), _summary(out, "smart")
    figures["smart_lateness_p99_ms"] = smart.get("lateness_p99_ms")
    view = next((m for m in umbra["modules"] if m["module"] == "view"), None)
    if view is not None:
        figures["view_step_mean_us"] = view.get("mean_step_us")
        sent = view.get("video_frames_sent") or {}
        figures["frames_to_viser"] = sent.get("wrist", 0)
        figures["view_updates_sent"] = view.get("updates_sent")
    return figures


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="short runs (a smoke run)")
    parser.add_argument(
        "--policy",
        choices=sorted(POLICIES),
        default="fifo",
        help="the servo process's scheduling: fifo (as shipped; results view3d.json) or default "
        "(results view3d_default_policy.json)",
    )
    args = parser.parse_args()
    if not CHROMIUM.exists():
        print(f"bench_view3d: needs Chromium at {CHROMIUM}", file=sys.stderr)
        return 2
    duration = 14.0 if args.quick else 25.0
    rounds = 1 if args.quick else 3
    phases = ("no view", "view, nobody watching", *VIEWPORTS)
    runs: dict[str, list[dict[str, Any]]] = {phase: [] for phase in phases}
    with tempfile.TemporaryDirectory(prefix="bench-view3d-") as tmp:
        for k in range(rounds):  # phases interleaved: a machine's load drifts over minutes
            for phase in phases:
                runs[phase].append(run_phase(Path(tmp) / f"round{k}", phase, duration, args.policy))
    results: dict[str, Any] = {}
    for phase in phases:
        merged: dict[str, Any] = {"rounds": runs[phase]}
        for key in runs[phase][0]:
            values = [r[key] for r in runs[phase] if isinstance(r.get(key), (int, float))]
            if values:
                merged[key] = float(np.median(values))
        results[phase] = merged
    base = results["no view"]["smart_lateness_p99_ms"]
    rows = []
    for phase in phases:
        r = results[phase]
        late = r["smart_lateness_p99_ms"]
        r["lateness_ratio"] = round(late / base, 3) if base and late is not None else None
        rows.append(
            [
                phase,
                late,
                r["lateness_ratio"],
                r.get("view_step_mean_us", "-"),
                r.get("frames_to_viser", "-"),
                r.get("browser_fps", "-"),
                r.get("browser_mb_per_s", "-"),
            ]
        )
    print(
        f"3-D view cost: median of {rounds} interleaved rounds of {duration:g} s; 1280x720 "
        f"camera at 30 fps; 100 Hz servo chain in `smart` ({args.policy} policy); view max_fps 15"
    )
    print(
        table(
            rows,
            [
                "phase",
                "smart p99 late ms",
                "ratio",
                "view step us",
                "frames to viser",
                "browser fps",
                "browser MB/s",
            ],
        )
    )
    path = write_results(
        "view3d" if args.policy == "fifo" else "view3d_default_policy",
        {"duration_s": duration, "rounds": rounds, "smart_policy": args.policy, "phases": results},
        quick=args.quick,
    )
    print(f"results: {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
