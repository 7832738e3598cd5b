"""Shared helpers for benchmarks: tables, JSON results, percentiles."""

from __future__ import annotations

import json
import os
import platform
import subprocess
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

RESULTS = Path(__file__).resolve().parent / "results"


def plugin_env(tmp: Path, name: str, entry_points: dict[str, str]) -> dict[str, str]:
    """The environment of an ``umbra`` child process that sees ``entry_points`` (module type ->
    ``module:Class``) registered as a third-party package registers them (a dist-info named
    ``name`` in ``tmp``), with the benchmarks' folder and the repository importable."""
    dist = tmp / f"umbra_{name.replace('-', '_')}-0.1.dist-info"
    dist.mkdir(exist_ok=True)
    (dist / "METADATA").write_text(f"Metadata-Version: 2.1\nName: umbra-{name}\nVersion: 0.1\n")
    lines = "".join(f"{k} = {v}\n" for k, v in entry_points.items())
    (dist / "entry_points.txt").write_text(f"[umbra.modules]\n{lines}")
    here = Path(__file__).resolve().parent
    folders = [str(tmp), str(here), str(here.parent), os.environ.get("PYTHONPATH", "")]
    path = os.pathsep.join(folders)
    return dict(os.environ, PYTHONPATH=path.rstrip(os.pathsep))


def percentiles(values: Any, qs: tuple[float, ...] = (50, 99)) -> dict[str, float]:
    """``{"p50": ..., "p99": ..., "max": ...}`` of ``values``."""
    arr = np.asarray(values, dtype=float)
    out = {f"p{q:g}": float(np.percentile(arr, q)) for q in qs}
    out["max"] = float(arr.max())
    return out


def table(rows: list[list[Any]], header: list[str]) -> str:
    """A plain-text table."""
    text = [[str(h) for h in header]] + [[_fmt(c) for c in row] for row in rows]
    widths = [max(len(r[i]) for r in text) for i in range(len(header))]
    lines = []
    for i, row in enumerate(text):
        lines.append(
            "  ".join(
                c.rjust(w) if j else c.ljust(w)
                for j, (c, w) in enumerate(zip(row, widths, strict=True))
            )
        )
        if i == 0:
            lines.append("  ".join("-" * w for w in widths))
    return "\n".join(lines)


def _fmt(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


def write_results(name: str, data: dict[str, Any], *, quick: bool) -> Path:
    """Write ``benchmarks/results/<name>.json`` with machine information; a quick run writes
    ``<name>.quick.json`` instead, so a smoke run never replaces the reference figures (``umbra
    bench`` looks for the file by the same rule)."""
    RESULTS.mkdir(parents=True, exist_ok=True)
    path = RESULTS / (f"{name}.quick.json" if quick else f"{name}.json")
    payload = {
        "benchmark": name,
        "quick": quick,
        "when": time.strftime("%Y-%m-%dT%H:%M:%S"),
        "machine": {
            "python": platform.python_version(),
            "cpu": platform.processor() or platform.machine(),
        },
        **data,
    }
    path.write_text(json.dumps(payload, indent=2, default=float))
    return path


#: The servo process's scheduling in the benchmarks that compare it with a page open: the graph's
#: `processes.smart` entry for SCHED_FIFO (as the shipped graphs ask) and for the default policy.
POLICIES = {"fifo": "{realtime_priority: 50}", "default": "{}"}

#: The simulated arm in the `smart` process, as the benchmarks with a page beside a servo loop
#: run it: `modules:` entries of a graph's YAML (a value for ``str.format``, not a template): a
#: constant 1 mm/s camera twist at 100 Hz through REG_VEL, ROTATE_KIN and WOLVERINE_KIN to the
#: simulated joints (WOLVERINE_JNTS, ``sim``), which start at the ready pose above the tool.
SIM_ARM_SMART = """
  command:
    type: TwistSource
    process: smart
    rate: 100
    params: {twist: [0.001, 0, 0, 0, 0, 0]}
  register: {type: REG_VEL, process: smart, rate: 100, params: {timeout: 0.1}}
  rotate: {type: ROTATE_KIN, process: smart}
  kinematics: {type: WOLVERINE_KIN, process: smart, params: {tool_xyz: [0, 0, 0.14]}}
  joints:
    type: WOLVERINE_JNTS
    process: smart
    rate: 100
    params: {backend: sim, initial_q_deg: [14.482, 45.603, -182.743, 0.0, -42.86, -165.518]}
""".strip("\n")
#: the connections of :data:`SIM_ARM_SMART` (`connections:` entries of the same graph)
SIM_ARM_SMART_WIRES = """
  - command.twist -> register.command
  - register.twist -> rotate.camera_twist
  - rotate.tool_twist -> kinematics.tool_twist
  - kinematics.joint_rates -> joints.rates
  - joints.joint_state ~> kinematics.joint_state
""".strip("\n")


def start_graph(
    graph: Path, out: Path, duration: float, address_after: str | None
) -> tuple[subprocess.Popen, str]:
    """``umbra run graph`` for ``duration`` seconds into ``out``; with ``address_after``, waits
    (60 s at most) for the log line holding it and returns the address that follows it."""
    proc = subprocess.Popen(
        ["umbra", "run", str(graph), "--duration", str(duration), "--out", str(out), "--quiet"],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    found: list[str] = []
    got = threading.Event()

    def read() -> None:
        assert proc.stdout is not None
        for line in proc.stdout:  # read to the end: a full pipe would stall the run
            if address_after and address_after in line and not found:
                found.append(line.split(address_after, 1)[1].strip())
                got.set()

    threading.Thread(target=read, daemon=True).start()
    if address_after and not got.wait(60):
        proc.kill()
        raise RuntimeError(f"the run did not print {address_after!r}")
    return proc, found[0] if found else ""
