"""Running tool pick-up trials on the runtime: one graph, many randomized set-ups.

This is an application of the runtime (as a user's script would be): it loads the graph with
per-trial parameter overrides, runs it on the sim clock in one process (or split over two
processes through ``umbra run``), and reads the module summaries back.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from umbra.modules.arm.wolverine_jnts import WolverineJnts
from umbra.modules.world.grasp import GraspError
from umbra.modules.world.trial_faults import (
    VISION_LAG_S,
    VISION_LAG_WINDOW_S,
    Overload,
    stop_and_continue,
)
from umbra.modules.world.trials import (
    STILL_SPEED,
    Nominal,
    TrialResult,
    TrialSetup,
    open_loop_grab,
    stale_travel,
    stop_figures,
)
from umbra.modules.world.world import WorldParams
from umbra.runtime.graph.check import load_graph
from umbra.runtime.graph.plan import GraphPlan
from umbra.runtime.links.config import free_loopback_ports
from umbra.runtime.run import run_process
from umbra.runtime.scheduler import SchedulerOptions

#: Types whose instances a trial configures.
ROLES = {
    "World": "world",
    "DigiCam": "camera",
    "WOLVERINE_JNTS": "joints",
    "Overlay": "view",
    "StatusPlot": "plot",
    "vsServo": "servo",
    "REG_VEL": "register",
    "SafetyMonitor": "monitor",
    "Recorder": "recorder",
    "OperatorConsole": "console",
    "OperatorSim": "operator",
}


class TrialGraph:
    """A pick-up graph and the names of the modules a trial sets, found by type."""

    def __init__(self, path: str | Path) -> None:
        self.path = str(path)
        self.plan: GraphPlan = load_graph(self.path)
        self.names: dict[str, str] = {}
        for name, mplan in self.plan.modules.items():
            role = ROLES.get(mplan.spec.type)
            if role and role not in self.names:
                self.names[role] = name
        missing = [r for r in ("world", "camera", "joints", "servo") if r not in self.names]
        if missing:
            from umbra.connectors.errors import UserError

            raise UserError(
                f"{self.path}: a pick-up graph needs modules of types World, "
                f"DigiCam, WOLVERINE_JNTS and vsServo; missing: {', '.join(missing)}"
            )
        joints = self.plan.modules[self.names["joints"]].params
        world = self.plan.modules[self.names["world"]].params
        # found by their types' names, so of these types' parameter classes
        assert isinstance(joints, WolverineJnts.Params) and isinstance(world, WorldParams)
        self.arm = joints.table  # the arm the graph drives, for the open-loop baseline
        self.q0 = np.radians(joints.initial_q_deg or [0.0] * self.arm.n)
        self.tolerance = (world.position_tolerance_mm, world.roll_tolerance_deg)
        self.T_base_table = self.plan.frames.lookup("base", "table")
        self.T_flange_tool = self.plan.frames.lookup("flange", "tool")

    def overrides(
        self, setup: TrialSetup, *, keep_media: bool, timeout_s: float
    ) -> dict[str, dict[str, Any]]:
        """``--set`` values that make the graph play ``setup``."""
        n = self.names
        out: dict[str, dict[str, Any]] = {
            n["world"]: {
                "tool_xy_m": list(setup.tool_xy_m),
                "tool_yaw_deg": setup.tool_yaw_deg,
                "patch_height_m": setup.patch_height_m,
                "timeout_s": timeout_s,
            },
            n["camera"]: {
                "gain": setup.gain,
                "cast_rgb": list(setup.cast_rgb),
                "noise_sigma": setup.noise_sigma,
                "background": "photo",
            },
            n["joints"]: {"calibration_error_deg": list(setup.calibration_error_deg)},
            n["servo"]: {"progress_period_s": 0.0},
        }
        if "console" in n:  # trials run unattended: no web page, the simulated operator clicks
            out[n["console"]] = {"serve": False}
        if "operator" in n:
            out[n["operator"]] = {"click_delay_s": 0.2}
        if setup.fault == "vision_lag":  # in one process: frames of the past for a while
            out[n["camera"]].update(
                {
                    "fault": "lag",
                    "fault_at_s": setup.fault_at_s,
                    "fault_lag_s": VISION_LAG_S,
                    "fault_duration_s": VISION_LAG_WINDOW_S,
                }
            )
        elif setup.fault == "overload" and "console" in n:  # a real page on the console
            out[n["console"]] = {"serve": True}
        elif setup.fault not in ("none", "kill_umbra", "overload"):
            out[n["camera"]].update({"fault": setup.fault, "fault_at_s": setup.fault_at_s})
        if not keep_media:
            if "view" in n:
                out[n["view"]] = {"video": ""}
            if "plot" in n:
                out[n["plot"]] = {"path": ""}
        return out

    def open_loop(self, setup: TrialSetup) -> GraspError | None:
        """The open-loop grab's error for ``setup`` (None: no IK solution)."""
        return open_loop_grab(self.arm, setup, self.T_base_table, self.T_flange_tool, self.q0)


def _result(
    graph: TrialGraph,
    setup: TrialSetup,
    summaries: dict[str, dict[str, Any]],
    t_fault: float | None = None,
) -> TrialResult:
    """The trial's result from the module summaries. ``t_fault``: when the fault was injected
    from outside (default: the camera's ``fault_started_at``)."""
    n = graph.names
    world = summaries.get(n["world"], {})
    servo = summaries.get(n["servo"], {})
    register = summaries.get(n.get("register", ""), {})
    if t_fault is None:
        t_fault = summaries.get(n["camera"], {}).get("fault_started_at")
    err = graph.open_loop(setup)
    position_mm, roll_deg = graph.tolerance
    ol_ok = err is not None and err.position_mm <= position_mm and abs(err.roll_deg) <= roll_deg
    safety: dict[str, Any] = {}
    monitor = summaries.get(n.get("monitor", ""), {})
    record = np.asarray(monitor.get("record") or [], dtype=float)
    if setup.fault != "none" and t_fault is not None and record.size:
        safety = stop_figures(record, t_fault, monitor.get("still_speed", STILL_SPEED))
    safety.update(stale_travel(record, register.get("stale_episodes_s") or []))
    assist = servo.get("assist_reason", "") or ""
    if setup.fault == "kill_umbra":
        assist = register.get("last_zero_reason", "") or assist
    return TrialResult(
        setup=setup,
        grasped=bool(world.get("grasped", False)),
        verdict=str(world.get("verdict", "no verdict (world summary missing)")),
        position_error_mm=world.get("position_error_mm"),
        roll_error_deg=world.get("roll_error_deg"),
        time_s=world.get("time_s"),
        stage=str(servo.get("stage", "?")),
        assist_reason=assist,
        stage_times_s=dict(servo.get("stage_times_s", {})),
        open_loop_error_mm=None if err is None else err.position_mm,
        open_loop_roll_deg=None if err is None else err.roll_deg,
        open_loop_success=bool(ol_ok),
        safety=safety,
        outcome=str(world.get("outcome", "")),
    )


def run_single(
    graph: TrialGraph,
    setup: TrialSetup,
    out_dir: Path,
    *,
    timeout_s: float = 40.0,
    keep_media: bool = False,
) -> TrialResult:
    """One trial in one process on the sim clock."""
    plan = load_graph(
        graph.path, overrides=graph.overrides(setup, keep_media=keep_media, timeout_s=timeout_s)
    )
    # overload is a matter of real time: the sim clock would only run slower
    clock = "real" if setup.fault == "overload" else "sim"
    options = SchedulerOptions(clock=clock, duration=timeout_s + 1.0, output_dir=out_dir)
    if setup.fault == "overload":
        with Overload():
            result = run_process(plan, options)
    else:
        result = run_process(plan, options)
    summaries = {m.name: m.extra for m in result.modules}
    return _result(graph, setup, summaries)


def run_split(
    graph: TrialGraph,
    setup: TrialSetup,
    out_dir: Path,
    *,
    timeout_s: float = 40.0,
    keep_media: bool = False,
) -> TrialResult:
    """One trial split over two processes (real clock, zenoh). For ``kill_umbra`` the processes
    are started separately, as on two hosts, and the vision process is killed mid-approach."""
    out_dir.mkdir(parents=True, exist_ok=True)
    sets = []
    for module, values in graph.overrides(
        setup, keep_media=keep_media, timeout_s=timeout_s
    ).items():
        for key, value in values.items():
            sets += ["--set", f"{module}.{key}={json.dumps(value)}"]
    base = [
        sys.executable,
        "-m",
        "umbra.runtime.cli.main",
        "run",
        graph.path,
        "--clock",
        "real",
        "--duration",
        str(timeout_s + 2.0),
        "--out",
        str(out_dir),
        "--quiet",
        *sets,
    ]
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    t_fault: float | None = None
    if setup.fault == "overload":
        _overloaded(base, env, timeout_s)
    elif setup.fault not in ("kill_umbra", "vision_lag"):
        subprocess.run(base, capture_output=True, text=True, env=env, timeout=timeout_s + 60)
    else:
        names = [n for n in graph.plan.populated_processes if n != "umbra"] + ["umbra"]
        ports = free_loopback_ports(len(names))
        endpoints: list[str] = []
        procs: dict[str, subprocess.Popen[str]] = {}
        for name, port in zip(names, ports, strict=True):  # a full mesh, smart first, as on
            args = [*base, "--process", name, "--listen", f"tcp/127.0.0.1:{port}"]  # hosts
            for endpoint in endpoints:  # that each listen and join the ones already up
                args += ["--connect", endpoint]
            endpoints.append(f"tcp/127.0.0.1:{port}")
            procs[name] = subprocess.Popen(
                args,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.PIPE if name == "umbra" else subprocess.DEVNULL,
                text=True,
                env=env,
            )
        umbra, smart = procs["umbra"], procs["smart"]
        others = [p for n, p in procs.items() if n not in ("smart", "umbra")]
        started = None
        assert umbra.stderr is not None
        for line in umbra.stderr:
            if "links ready" in line:
                started = time.monotonic()
                break
        threading.Thread(target=umbra.stderr.read, daemon=True).start()  # never blocks it
        if started is not None:
            time.sleep(max(0.0, started + setup.fault_at_s - time.monotonic()))
            t_fault = time.monotonic()
            if setup.fault == "kill_umbra":
                umbra.send_signal(signal.SIGKILL)
            else:  # vision_lag: the vision process loses its CPU, then goes on
                stop_and_continue(umbra)
        smart.wait(timeout=timeout_s + 60)
        for rest in [umbra, *others]:  # the judge has spoken: the others stop now
            if rest.poll() is None:
                rest.send_signal(signal.SIGINT)
            try:
                rest.wait(timeout=30)
            except subprocess.TimeoutExpired:
                rest.kill()
                rest.wait()
    summaries: dict[str, dict[str, Any]] = {}
    for path in out_dir.glob("summary*.json"):
        data = json.loads(path.read_text())
        for m in data.get("modules", []):
            summaries[m["module"]] = m
    return _result(graph, setup, summaries, t_fault)


def _overloaded(base: list[str], env: dict[str, str], timeout_s: float) -> None:
    """Run the split graph under ``Overload``, with the console's page open in Chromium as soon
    as the run prints its address."""
    with Overload() as load:
        run = subprocess.Popen(
            base, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env
        )
        assert run.stdout is not None
        for line in run.stdout:
            found = CONSOLE_URL.search(line)
            if found:
                load.page(found.group(0))
                break
        threading.Thread(target=run.stdout.read, daemon=True).start()
        run.wait(timeout=timeout_s + 60)


#: The operator console's address in a run's output (with its per-run token).
CONSOLE_URL = re.compile(r"http://(127\.0\.0\.1|localhost|\[::1\]):\d+/\S*")

__all__ = ["Nominal", "TrialGraph", "run_single", "run_split"]
