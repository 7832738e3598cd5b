"""Nothing moves on old data: the pick-up with a vision side that falls behind, is stopped and
continued, or shares an overloaded machine with the operator's page.

Before origins, each of these drove the arm on the past: REG_VEL judged a command by its arrival,
and a command computed now from an image seconds old arrived "fresh". Now the true tool may travel
at most ``MAX_STALE_TRAVEL_MM`` while the guard's newest data is older than its bound, and every
trial grasps or stops.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from umbra.connectors.states import Outcome
from umbra.modules.world.trial_faults import MAX_STALE_TRAVEL_MM
from umbra.modules.world.trial_runner import TrialGraph, run_single, run_split
from umbra.modules.world.trials import TrialResult, draw_trial

GRAPH = str(Path(__file__).resolve().parents[2] / "graphs" / "tool_pickup.yaml")


@pytest.fixture(scope="module")
def graph() -> TrialGraph:
    return TrialGraph(GRAPH)


def _safe(result: TrialResult) -> None:
    """A grasp, or a stop: never a grab closed in the wrong place (a judged miss), and never more
    than 5 mm of travel while the guard's data was too old."""
    assert result.outcome in set(Outcome), result.verdict  # the world judged the run
    assert not result.closed_off_target, result.verdict
    assert result.safety["travel_while_stale_mm"] <= MAX_STALE_TRAVEL_MM, result.safety


@pytest.mark.slow
@pytest.mark.heavy
@pytest.mark.timeout(600)
def test_frames_of_the_past_stop_the_arm_however_fresh_the_commands(
    graph: TrialGraph, tmp_path: Path
) -> None:
    """One process, sim clock (deterministic): mid-approach the camera's frames fall 2 s behind
    the scene (slow motion, each stamped with its capture time), as those a starved vision loop
    takes from a queue. The servo keeps commanding from them on time; the register refuses."""
    setup = draw_trial(7, 1, fault="vision_lag", fault_window_s=(3.0, 3.5))
    result = run_single(graph, setup, tmp_path)
    _safe(result)
    assert result.safety["stale_episodes"] >= 1  # the register saw the old data and held
    assert result.grasped, result.verdict  # and once the frames caught up, the grab went on


@pytest.mark.slow
@pytest.mark.heavy
@pytest.mark.timeout(600)
def test_a_stopped_and_continued_vision_process_never_moves_the_arm_on_what_it_saw_before(
    graph: TrialGraph, tmp_path: Path
) -> None:
    """Split: the vision process is SIGSTOPped for 2 s mid-approach, then continued; what it
    computes from the frames it held is refused, and the tool moves at most 5 mm on it."""
    setup = draw_trial(7, 3, fault="vision_lag", fault_window_s=(2.5, 3.0))
    result = run_split(graph, setup, tmp_path, timeout_s=20)
    _safe(result)
    assert result.safety["stale_episodes"] >= 1, result.safety


@pytest.mark.slow
@pytest.mark.heavy
@pytest.mark.timeout(600)
def test_an_overloaded_machine_with_the_page_open_grasps_or_stops(
    graph: TrialGraph, tmp_path: Path
) -> None:
    """Split, four busy processes per core and the console open in Chromium: the control path
    either stays fresh (a grasp) or the arm stops."""
    setup = draw_trial(7, 2, fault="overload")
    result = run_split(graph, setup, tmp_path, timeout_s=30)
    _safe(result)
