"""Freshness benchmark: how old the data behind the servo's commands is, healthy and overloaded.

Runs the pick-up (``graphs/tool_pickup.yaml``) on the real clock, split over its processes and in
one process, under CPU overload made by busy processes (``OVERLOAD_FACTOR`` × cores: none, 2×,
4×), with and without the operator's page open in Chromium, and reads REG_VEL's summary: the
origin age of every command it passed (capture of the image → command at the register) beside the
same commands' arrival age (what the register judged before origins existed), the watchdog zeroes
(a command stream that paused past its 0.1 s timeout), the stretches at zero for old data and how
far the true tool travelled during them (SafetyMonitor's record), and the run's verdict.

Then the cost of carrying the origin on a small link round trip: a 6-vector twist ping-ponged over
two zenoh sessions on loopback, msgspec-encoded with and without the origin field, the receiver
bringing the origin onto its clock as the transport does — ratio of the round trips, same run,
the two kinds alternating round by round so that a change of load hits both alike.

Goals (issue #28): healthy with a page open, command origin age p99 <= 150 ms and no watchdog
zero; under 4x overload every run grasps or stops with at most 5 mm of travel on stale data; the
stamp's cost <= 3 % of the round trip.

    python benchmarks/bench_freshness.py            # about 6 minutes
    python benchmarks/bench_freshness.py --quick    # the split runs only, shorter
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import msgspec
import numpy as np
import zenoh

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.common import percentiles, table, write_results
from umbra.modules.world.trial_faults import MAX_STALE_TRAVEL_MM, Overload
from umbra.modules.world.trial_runner import CONSOLE_URL
from umbra.modules.world.trials import stale_travel
from umbra.runtime.links.clock_sync import Offset, on_our_clock
from umbra.runtime.links.config import free_loopback_ports

GRAPH = Path(__file__).resolve().parent.parent / "graphs" / "tool_pickup.yaml"
#: Goals of issue #28.
HEALTHY_P99_MS = 150.0
STAMP_COST_RATIO = 1.03


def run_pickup(split: bool, factor: int, page: bool, duration: float) -> dict[str, Any]:
    """One pick-up run; REG_VEL's and World's figures from its summaries."""
    out = Path(tempfile.mkdtemp(prefix="bench-freshness-"))
    cmd = [
        sys.executable,
        "-m",
        "umbra.runtime.cli.main",
        "run",
        str(GRAPH),
        "--duration",
        str(duration),
    ]
    cmd += ["--out", str(out), "--quiet"]
    if not split:
        cmd += ["--single-process", "--clock", "real"]
    if not page:
        cmd += ["--set", "console.serve=false"]
    started = time.monotonic()
    with Overload(factor) as load:  # factor 0: no busy process, only the page if any
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        assert proc.stdout is not None
        opened = False
        lines = []
        for line in proc.stdout:
            lines.append(line)
            if page and not opened and (found := CONSOLE_URL.search(line)):
                opened = load.page(found.group(0))
        proc.wait()
    modules: dict[str, dict[str, Any]] = {}
    for path in out.glob("summary*.json"):
        for m in json.loads(path.read_text()).get("modules", []):
            modules[m["module"]] = m
    register, world = modules.get("register", {}), modules.get("world", {})
    record = np.asarray(modules.get("monitor", {}).get("record") or [], dtype=float)
    stale = stale_travel(record, register.get("stale_episodes_s") or [])
    return {
        "split": split,
        "overload": factor,
        "page": page and opened,
        "wall_s": round(time.monotonic() - started, 1),
        "grasped": bool(world.get("grasped")),
        "verdict": world.get("verdict", "".join(lines[-3:]).strip()),
        "origin_age_ms": register.get("passed_origin_age_ms", {}),
        "arrival_age_ms": register.get("passed_arrival_age_ms", {}),
        "watchdog_zeroes": register.get("watchdog_zeroes"),
        "stale_zero_ticks": register.get("stale_zero_ticks"),
        **stale,
    }


class _Plain(msgspec.Struct, array_like=True):
    stamp: float
    seq: int
    vector: bytes
    frame: str


class _Stamped(msgspec.Struct, array_like=True):
    stamp: float
    seq: int
    origin: float
    vector: bytes
    frame: str


def stamp_cost(rounds: int) -> dict[str, Any]:
    """Round trips [µs] of a small twist without and with its origin (translated on arrival)."""
    (port,) = free_loopback_ports(1)

    def config(key: str) -> zenoh.Config:
        text = json.dumps(
            {
                "scouting": {"multicast": {"enabled": False}, "gossip": {"enabled": False}},
                key: {"endpoints": [f"tcp/127.0.0.1:{port}"]},
            }
        )
        return zenoh.Config.from_json5(text)

    a, b = zenoh.open(config("listen")), zenoh.open(config("connect"))
    time.sleep(0.5)
    vector = np.zeros(6).tobytes()
    offset = Offset(0.0021, 0.0001, 0.0002, 8)  # another host's clock: the translation runs
    translate = on_our_clock(offset)
    assert translate is not None
    kinds = {"plain": _Plain, "stamped": _Stamped}
    results: dict[str, list[float]] = {kind: [] for kind in kinds}
    got = threading.Event()
    encoder = msgspec.msgpack.Encoder()
    subscribers = []
    try:
        for kind, cls in kinds.items():
            decoder = msgspec.msgpack.Decoder(cls)

            def echo(sample: zenoh.Sample, _d=decoder, _k=kind) -> None:
                msg = _d.decode(sample.payload.to_bytes())
                if isinstance(msg, _Stamped):
                    stamp, origin = translate(msg.stamp, msg.origin)
                    msg = msgspec.structs.replace(msg, stamp=stamp, origin=origin)
                b.put(f"bench/{_k}/pong", encoder.encode(msg))

            def back(sample: zenoh.Sample, _d=decoder) -> None:
                _d.decode(sample.payload.to_bytes())
                got.set()

            subscribers.append(b.declare_subscriber(f"bench/{kind}/ping", echo))
            subscribers.append(a.declare_subscriber(f"bench/{kind}/pong", back))
        time.sleep(0.3)
        # The two kinds alternate round by round, so a change of load hits both alike.
        for i in range(2 * (rounds + 200)):
            kind = ("plain", "stamped")[i % 2]
            now = time.monotonic()
            fields = dict(stamp=now, seq=i, vector=vector, frame="camera")
            msg = _Stamped(origin=now - 0.03, **fields) if kind == "stamped" else _Plain(**fields)
            got.clear()
            t0 = time.perf_counter()
            a.put(f"bench/{kind}/ping", encoder.encode(msg))
            if not got.wait(1.0):
                continue
            if i >= 400:  # warm-up rounds left out
                results[kind].append((time.perf_counter() - t0) * 1e6)
    finally:
        for subscriber in subscribers:
            subscriber.undeclare()
        a.close()
        b.close()
    plain, stamped = percentiles(results["plain"]), percentiles(results["stamped"])
    return {
        "plain_us": plain,
        "stamped_us": stamped,
        "ratio_p50": stamped["p50"] / plain["p50"],
        "rounds": rounds,
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="split runs only, shorter")
    args = parser.parse_args()
    duration = 25.0 if args.quick else 30.0
    configs = [(True, f, p) for f in (0, 2, 4) for p in (False, True)]
    if not args.quick:
        configs += [(False, 0, False), (False, 4, False)]
    runs = []
    for split, factor, page in configs:
        print(f"run: {'split' if split else 'single'}, overload {factor}x, page {page}", flush=True)
        runs.append(run_pickup(split, factor, page, duration))
    cost = stamp_cost(500 if args.quick else 2000)
    rows = [
        [
            "split" if r["split"] else "single",
            f"{r['overload']}x",
            "yes" if r["page"] else "no",
            r["origin_age_ms"].get("p50"),
            r["origin_age_ms"].get("p99"),
            r["arrival_age_ms"].get("p99"),
            r["watchdog_zeroes"],
            r["stale_episodes"],
            r["travel_while_stale_mm"],
            "grasped" if r["grasped"] else r["verdict"][:40],
        ]
        for r in runs
    ]
    print(
        table(
            rows,
            [
                "processes",
                "load",
                "page",
                "origin p50 ms",
                "origin p99 ms",
                "arrival p99 ms",
                "watchdog 0s",
                "stale",
                "travel stale mm",
                "outcome",
            ],
        )
    )
    print(
        f"stamp on a small round trip: {cost['plain_us']['p50']:.1f} us without, "
        f"{cost['stamped_us']['p50']:.1f} us with (ratio {cost['ratio_p50']:.3f}, goal <= "
        f"{STAMP_COST_RATIO})"
    )
    healthy = [r for r in runs if r["split"] and r["overload"] == 0 and r["page"]]
    overloaded = [r for r in runs if r["overload"] == 4]
    goals = {
        "healthy_page_origin_p99": bool(healthy)
        and all((r["origin_age_ms"].get("p99") or 1e9) <= HEALTHY_P99_MS for r in healthy),
        "healthy_page_no_watchdog_zero": bool(healthy)
        and all(r["watchdog_zeroes"] == 0 for r in healthy),
        "overload_grasp_or_safe_stop": all(
            r["travel_while_stale_mm"] <= MAX_STALE_TRAVEL_MM for r in overloaded
        ),
        "stamp_cost": cost["ratio_p50"] <= STAMP_COST_RATIO,
    }
    print("goals: " + ", ".join(f"{k} {'met' if v else 'MISSED'}" for k, v in goals.items()))
    path = write_results(
        "freshness", {"runs": runs, "stamp_cost": cost, "goals": goals}, quick=args.quick
    )
    print(f"results: {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
