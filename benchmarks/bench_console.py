"""Operator console benchmark: glass-to-glass latency, frames shown, CPU, servo lateness, clicks.

For each camera size (640x480 and 1280x720 at 30 fps) and each scheduling of the servo process
(``--policies``: SCHED_FIFO priority 50 as the shipped graphs ask, and the default policy) the
same two-process graph runs twice in this benchmark run: a camera (a looping MJPEG clip decoded
in DigiCam's reader thread, as a device would be) and the console in `umbra`, a 100 Hz REG_VEL
loop in `smart`. The first run has no page open (the same-run baseline); the second has a real
Chromium page (Debian's, via Playwright) that holds control and clicks the image every 0.4 s.

Figures: latency from a frame's stamp to the browser painting it (the page reports it to the
console), frames painted per second, the console's CPU share of the `umbra` process (its web
and encoder threads plus its module steps), the `smart` process's tick lateness p99 with and
without the page (ratio), and the time from a click reaching the console's web thread to the
seed leaving its `seed` output (p95; the snake reads it with its next frame).

    python benchmarks/bench_console.py [--quick] [--policies fifo,default]
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

from benchmarks.common import POLICIES, start_graph, table, write_results
from tests.browser import CHROMIUM, launch

GOALS = {"latency_p95_ms": 100.0, "fps_shown": 25.0, "seed_latency_p95_ms": 50.0}

GRAPH = """
graph: bench_console
seed: 0
clock: real
processes: {{umbra: {{}}, smart: {smart}}}
modules:
  camera:                     # a video file, decoded in DigiCam's reader thread (as a device)
    type: DigiCam
    process: umbra
    rate: 30
    params: {{source: "{video}", at_end: loop}}
  console: {{type: OperatorConsole, process: umbra, rate: 100}}
  command:
    type: TwistSource
    process: smart
    rate: 100
    params: {{twist: [0.001, 0, 0, 0, 0, 0]}}
  register: {{type: REG_VEL, process: smart, rate: 100, params: {{timeout: 0.1}}}}
connections:
  - camera.image -> console.image
  - command.twist -> register.command
"""


def _video(folder: Path, w: int, h: int, frames: int = 90) -> Path:
    """A looping MJPEG clip: a table, a green patch drifting, sensor noise."""
    import cv2
    import numpy as np

    path = folder / f"clip_{w}x{h}.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 30.0, (w, h))
    rng = np.random.default_rng(0)
    for k in range(frames):
        img = np.full((h, w, 3), (90, 110, 130), np.uint8)
        cu = int(w * (0.45 + 0.05 * np.sin(2 * np.pi * k / frames)))
        cv = h // 2
        img[cv - h // 10 : cv + h // 10, cu - w // 10 : cu + w // 10] = (60, 170, 30)
        noise = rng.normal(0, 3, img.shape)
        writer.write(np.clip(img + noise, 0, 255).astype(np.uint8))
    writer.release()
    return path


#: The servo process's scheduling: as the shipped graphs run it (SCHED_FIFO priority 50, which
#: needs root), and the default policy, where it shares the CPUs with the browser.
def _graph(folder: Path, w: int, h: int, policy: str) -> Path:
    path = folder / f"bench_console_{w}x{h}_{policy}.yaml"
    clip = folder / f"clip_{w}x{h}.avi"
    video = clip if clip.exists() else _video(folder, w, h)
    path.write_text(GRAPH.format(video=video, smart=POLICIES[policy]))
    return path


def _watch(url: str, seconds: float) -> dict[str, Any]:
    """A page that watches, holds control and clicks the image every 0.4 s."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        browser = launch(p)
        page = browser.new_page(viewport={"width": 1600, "height": 1000})
        page.goto(url)
        page.wait_for_function("window.umbra.painted > 2", timeout=20000)
        page.click("#take")
        page.wait_for_function(
            "window.umbra.state && window.umbra.state.control_session === window.umbra.session",
            timeout=10000,
        )
        box = page.locator("#video").bounding_box()
        end = time.monotonic() + seconds
        clicks = 0
        while time.monotonic() < end:
            page.mouse.click(box["x"] + box["width"] * 0.5, box["y"] + box["height"] * 0.5)
            clicks += 1
            page.wait_for_timeout(400)
        painted = page.evaluate("window.umbra.painted")
        browser.close()
    return {"clicks": clicks, "painted": painted}


def _summary(out: Path, process: str) -> dict[str, Any]:
    return json.loads((out / f"summary-{process}.json").read_text())


def _console_figures(umbra: dict[str, Any]) -> dict[str, Any]:
    console = next(m for m in umbra["modules"] if m["module"] == "console")
    camera = next(m for m in umbra["modules"] if m["module"] == "camera")
    steps_s = console["calls"] * console["mean_step_us"] * 1e-6
    cpu = console.get("web_cpu_s", 0.0) + console.get("encoder_cpu_s", 0.0) + steps_s
    process = console.get("process_cpu_s") or float("nan")
    return {
        "latency_p50_ms": console.get("latency_p50_ms"),
        "latency_p95_ms": console.get("latency_p95_ms"),
        "fps_shown": console.get("fps_shown"),
        "fps_produced": round(camera["frames"] / umbra["wall_time_s"], 2),
        "frames_painted": console.get("frames_painted", 0),
        "seed_latency_p95_ms": console.get("seed_latency_p95_ms"),
        "seeds": console.get("seeds", 0),
        "console_cpu_s": round(cpu, 3),
        "process_cpu_s": process,
        "console_cpu_share": round(cpu / process, 3) if process == process and process else None,
        "console_cpu_pct_of_core": round(100.0 * cpu / umbra["wall_time_s"], 1),
    }


def run_size(folder: Path, w: int, h: int, duration: float, policy: str) -> dict[str, Any]:
    graph = _graph(folder, w, h, policy)
    result: dict[str, Any] = {"size": f"{w}x{h}", "smart_policy": policy}
    for phase in ("baseline", "page"):
        out = folder / f"{w}x{h}-{policy}-{phase}"
        proc, url = start_graph(graph, out, duration, "operator console: ")
        page: dict[str, Any] = {}
        if phase == "page":
            page = _watch(url, duration - 6.0)
        proc.wait(duration + 60)
        umbra, smart = _summary(out, "umbra"), _summary(out, "smart")
        figures = _console_figures(umbra)
        figures["smart_lateness_p99_ms"] = smart.get("lateness_p99_ms")
        figures.update(page)
        result[phase] = figures
    base = result["baseline"]["smart_lateness_p99_ms"]
    with_page = result["page"]["smart_lateness_p99_ms"]
    result["lateness_ratio"] = round(with_page / base, 3) if base else None
    return result


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="short runs (a smoke run)")
    parser.add_argument(
        "--policies",
        default="fifo,default",
        help="the servo process's scheduling, comma-separated: fifo (as shipped), default",
    )
    args = parser.parse_args()
    policies = [p for p in args.policies.split(",") if p]
    if not policies or set(policies) - set(POLICIES):
        print(f"bench_console: --policies takes {', '.join(POLICIES)}", file=sys.stderr)
        return 2
    if not CHROMIUM.exists():
        print(f"bench_console: needs Chromium at {CHROMIUM}", file=sys.stderr)
        return 2
    duration = 12.0 if args.quick else 30.0
    results = []
    with tempfile.TemporaryDirectory(prefix="bench-console-") as tmp:
        for w, h in ((640, 480), (1280, 720)):
            for policy in policies:
                results.append(run_size(Path(tmp), w, h, duration, policy))
    rows = []
    for r in results:
        page, base = r["page"], r["baseline"]
        rows.append(
            [
                r["size"],
                r["smart_policy"],
                page["latency_p50_ms"],
                page["latency_p95_ms"],
                page["fps_shown"],
                page["fps_produced"],
                page["console_cpu_pct_of_core"],
                page["console_cpu_share"],
                base["console_cpu_share"],
                base["smart_lateness_p99_ms"],
                page["smart_lateness_p99_ms"],
                r["lateness_ratio"],
                page["seed_latency_p95_ms"],
            ]
        )
    header = [
        "camera",
        "smart policy",
        "g2g p50 ms",
        "g2g p95 ms",
        "fps shown",
        "camera fps",
        "console CPU % core",
        "share of umbra",
        "(no page)",
        "smart p99 late ms (no page)",
        "(page)",
        "ratio",
        "click->seed p95 ms",
    ]
    print(table(rows, header))
    print(f"goals at 640x480: {GOALS}")
    path = write_results(
        "console",
        {"duration_s": duration, "goals": GOALS, "results": results},
        quick=args.quick,
    )
    print(f"results: {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
