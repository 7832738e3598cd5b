"""The main job end to end: randomized pick-ups and injected faults, in one process on the sim
clock and split over two processes with zenoh."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from umbra.modules.world.trial_runner import TrialGraph, run_single, run_split
from umbra.modules.world.trials import draw_trial

GRAPH = str(Path(__file__).resolve().parents[2] / "graphs" / "tool_pickup.yaml")


@pytest.fixture(scope="module")
def graph() -> TrialGraph:
    return TrialGraph(GRAPH)


@pytest.mark.parametrize("index", [0, 1])
def test_randomized_pickup_grasps_within_two_mm_and_one_degree(
    graph: TrialGraph, index: int, tmp_path: Path
) -> None:
    setup = draw_trial(7, index)
    result = run_single(graph, setup, tmp_path)
    assert result.grasped, result.verdict
    assert result.position_error_mm <= 2.0 and abs(result.roll_error_deg) <= 1.0
    assert set(result.stage_times_s) >= {"acquire", "approach", "final_grab"}
    # the open-loop grab through the same miscalibrated arm misses by much more
    assert result.open_loop_error_mm > 3 * result.position_error_mm


@pytest.mark.parametrize("fault", ["occluder", "remove_patch", "distractor", "freeze"])
def test_injected_faults_stop_the_arm_and_ask_the_operator(
    graph: TrialGraph, fault: str, tmp_path: Path
) -> None:
    result = run_single(graph, draw_trial(7, 0, fault=fault, fault_window_s=(3.0, 3.5)), tmp_path)
    assert not result.grasped
    assert result.stage == "assist"
    assert result.assist_reason.startswith("snake failure")
    assert result.safety["stopped"], result.safety
    assert result.safety["time_to_standstill_s"] < 1.0


def test_split_pickup_over_zenoh_grasps(graph: TrialGraph, tmp_path: Path) -> None:
    result = run_split(graph, draw_trial(7, 2), tmp_path, timeout_s=30)
    assert result.grasped, result.verdict
    assert result.position_error_mm <= 2.0


def test_killing_the_vision_process_stops_the_servo_side_within_its_watchdog(
    graph: TrialGraph, tmp_path: Path
) -> None:
    setup = draw_trial(7, 3, fault="kill_umbra", fault_window_s=(2.5, 3.0))
    result = run_split(graph, setup, tmp_path, timeout_s=12)
    assert not result.grasped
    assert result.safety["stopped"], result.safety
    # REG_VEL's timeout is 0.1 s; liveliness usually reports the loss sooner
    assert result.safety["time_to_zero_command_s"] <= 0.15
    assert result.assist_reason


@pytest.mark.slow  # two sim pick-ups in a subprocess: 27 s quiet, ~2 min at load 10
@pytest.mark.heavy
@pytest.mark.timeout(330)
def test_trials_command_json(tmp_path: Path) -> None:
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "umbra.runtime.cli.main",
            "trials",
            GRAPH,
            "-n",
            "2",
            "--seed",
            "11",
            "--json",
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout)
    assert summary["trials"] == 2 and summary["success_rate"] == 1.0
    assert set(summary["final_error_mm"]) == {"median", "p95", "max"}
    assert set(summary["time_s"]) == {"median", "p95"}
    assert summary["open_loop_success_rate"] < 1.0
