"""A stopped servo process (SIGSTOP, as Ctrl-Z does) must not leave the arm running: the
simulated drive's own watchdog bounds the travel whatever the length of the stop.

A real `umbra run` process holds the servo side (a constant twist through REG_VEL, the
kinematics, WOLVERINE_JNTS and a SafetyMonitor that records the true tool point). The test
stops it with SIGSTOP for 1 s (5 s in the slow run), continues it with SIGCONT, and measures
in the monitor's record how far the true tool point went across the gap. Without a drive
watchdog the arm went on at its last rate: speed x gap (40 mm in 1 s, 200 mm in 5 s here).
Load: none needed beyond the processes themselves; the bound below depends only on the drive
model (the stop starts at most ``drive_watchdog`` after the last command).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

# whole runs of umbra in subprocesses, seconds each: in CI with -m slow (a short default run)
pytestmark = pytest.mark.slow

SPEED_M_S = 0.04  # the commanded tool speed along the camera's x axis
WATCHDOG_S = 0.1  # WOLVERINE_JNTS's drive_watchdog (its default)
LAG_S = 0.02  # WOLVERINE_JNTS's lag_tau (its default)

GRAPH = """graph: drive_watchdog
clock: real
frames:
  flange->tool: {{xyz: [0, 0, 0.14]}}
  tool->camera: {{xyz: [0, 0, -0.12]}}
modules:
  vision: {{type: TwistSource, rate: 100, params: {{twist: [{speed}, 0, 0, 0, 0, 0]}}}}
  reg: {{type: REG_VEL, rate: 100}}
  rot: {{type: ROTATE_KIN}}
  kin: {{type: WOLVERINE_KIN, params: {{tool_xyz: [0, 0, 0.14]}}}}
  jnts:
    type: WOLVERINE_JNTS
    rate: 100
    params: {{backend: {backend}, {extra}
              initial_q_deg: [14.482, 45.603, -182.743, 0.0, -42.86, -165.518]}}
  monitor: {{type: SafetyMonitor, rate: 100}}
  started: {{type: Printer, params: {{max_rate_hz: 1}}}}
connections:
  - vision.twist -> reg.command
  - reg.twist -> rot.camera_twist
  - rot.tool_twist -> kin.tool_twist
  - kin.joint_rates -> jnts.rates
  - jnts.joint_state ~> kin.joint_state
  - kin.joint_rates -> monitor.rates
  - jnts.{state} ~> monitor.true_state
  - jnts.status -> started.value
"""


def sigstop_travel(
    tmp_path: Path,
    stop_s: float,
    *,
    backend: str = "sim",
    extra: str = "",
    state: str = "true_joint_state",
) -> tuple[float, float, float]:
    """Run the servo side in its own process, SIGSTOP it ``stop_s`` seconds once the arm has
    moved for 1 s, SIGCONT it. Returns (travel across the stop (m), the tool speed before it
    (m/s), the stop seen in the record (s)). The travel is measured two ticks after the
    continue (the first record may still show the state of before), less what the fresh
    commands may have moved since."""
    graph = tmp_path / "servo.yaml"
    graph.write_text(GRAPH.format(speed=SPEED_M_S, backend=backend, extra=extra, state=state))
    out = tmp_path / "out"
    duration = 1.0 + stop_s + 6.0  # the clock may start before a slow bring-up of drives
    log = (tmp_path / "stderr.txt").open("w")  # a file: a full pipe would stall the run
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "umbra.runtime.cli.main",
            "run",
            str(graph),
            "--duration",
            str(duration),
            "--out",
            str(out),
            "--quiet",
        ],
        stdout=subprocess.PIPE,
        stderr=log,
        text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()  # the Printer's first line: the loop runs
        assert line, (tmp_path / "stderr.txt").read_text()[-3000:]
        time.sleep(1.0)
        proc.send_signal(signal.SIGSTOP)
        time.sleep(stop_s)
        proc.send_signal(signal.SIGCONT)
        proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        log.close()
    assert proc.returncode == 0, (tmp_path / "stderr.txt").read_text()[-3000:]
    summary = json.loads((out / "summary.json").read_text())
    (monitor,) = [m for m in summary["modules"] if m["module"] == "monitor"]
    record = np.asarray(monitor["record"], dtype=float)
    t, p = record[:, 0], record[:, 3:6]
    i = int(np.argmax(np.diff(t)))  # the stop: the longest gap between two records
    gap = t[i + 1] - t[i]
    before = (t > t[i] - 0.3) & (t <= t[i])
    speed = np.linalg.norm(p[before][-1] - p[before][0]) / (t[before][-1] - t[before][0])
    after = int(np.searchsorted(t, t[i + 1] + 0.015))
    travel = float(np.linalg.norm(p[after] - p[i])) - speed * (t[after] - t[i + 1] + 0.01)
    return travel, float(speed), float(gap)


def check(travel: float, speed: float, gap: float, stop_s: float, watchdog_s: float) -> None:
    assert gap >= stop_s * 0.9, f"the record shows no stop of {stop_s} s (longest gap {gap:.3f} s)"
    assert speed == pytest.approx(SPEED_M_S, rel=0.15)
    # the held command for the watchdog time, then the lag (sim) and the deceleration
    bound = speed * (watchdog_s + LAG_S) + 0.001
    print(
        f"stop {gap:.2f} s: travel {travel * 1000:.1f} mm (bound {bound * 1000:.1f} mm; "
        f"without a drive watchdog {speed * gap * 1000:.0f} mm)"
    )
    assert travel <= bound


@pytest.mark.timeout(120)
def test_sigstop_of_the_servo_process_for_1_s_moves_the_arm_a_watchdog_time_at_most(
    tmp_path: Path,
) -> None:
    travel, speed, gap = sigstop_travel(tmp_path, 1.0)
    check(travel, speed, gap, 1.0, WATCHDOG_S)


@pytest.mark.slow
@pytest.mark.timeout(120)
def test_sigstop_of_the_servo_process_for_5_s_moves_it_no_further(tmp_path: Path) -> None:
    travel, speed, gap = sigstop_travel(tmp_path, 5.0)
    check(travel, speed, gap, 5.0, WATCHDOG_S)
