"""The issue's live tuning, from Foxglove's own npm client (``@foxglove/ws-protocol``) on a split
pick-up: ``servo.gains = [-2, -2, -2, -2]`` is refused with the model's reason and never reaches
the vision process, which goes on; a good change of the gains is applied there; the pick-up ends
as it does without a viewer (exit 0, grasped)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.live.helpers import REPO, LiveRun, install_client, needs_node, run_tune, wait_joined

# a whole split pick-up in subprocesses: in CI with -m slow
pytestmark = pytest.mark.slow

GRAPH = REPO / "graphs" / "tool_pickup.yaml"
DEFAULT = [0.8, 0.8, 0.6, 0.8]
GOOD = [0.9, 0.9, 0.6, 0.9]
CHANGES = [
    {"at": 0.5, "name": "servo.gains", "value": [-2, -2, -2, -2]},
    {"at": 1.0, "name": "servo.gains", "value": [1, 1, 1]},
    {"at": 1.5, "name": "servo.gains", "value": "fast"},
    {"at": 2.0, "name": "snake.tension", "value": 3.0},
    {"at": 2.5, "name": "servo.gains", "value": GOOD},
]


@pytest.fixture(scope="module")
def tune_js(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return install_client(tmp_path_factory.mktemp("npm")).parent / "tune.js"


@needs_node
def test_negative_servo_gains_from_a_viewer_are_refused_and_the_run_goes_on(
    tune_js: Path, tmp_path: Path
) -> None:
    run = LiveRun(str(GRAPH), tmp_path / "run", "--duration", "60")
    try:
        wait_joined(run)
        report = run_tune(tune_js, run.url, 20.0, "", CHANGES)
        assert run.proc.poll() is None, run.text()[-3000:]  # every process still runs
        code = run.wait(120)
    finally:
        run.stop()
    log = run.text()
    assert report.get("error") is None, report["error"]
    said = [s["message"] for s in report["statuses"]]
    assert len(said) == 4, said
    assert said[0] == (
        "parameter `servo.gains` not changed: parameter `gains.0`: Input should be greater than "
        "or equal to 0, found -2; parameter `gains.1`: Input should be greater than or equal to "
        "0, found -2; parameter `gains.2`: Input should be greater than or equal to 0, found -2; "
        "parameter `gains.3`: Input should be greater than or equal to 0, found -2"
    )
    assert "parameter `gains`: List should have at least 4 items" in said[1]
    assert "parameter `gains`: Input should be a valid list" in said[2]
    assert "parameter `tension`: Input should be less than or equal to 0.5" in said[3]
    # the refused values are answered with the value in force; the good one is taken
    assert report["answers"]["set0"] == [{"name": "servo.gains", "value": DEFAULT}]
    assert report["answers"]["set3"] == [{"name": "snake.tension", "value": 0.2}]
    assert report["answers"]["set4"] == [{"name": "servo.gains", "value": GOOD}]
    assert (
        "[umbra]" in log and "param servo.gains [0.8, 0.8, 0.6, 0.8] -> [0.9, 0.9, 0.6, 0.9]" in log
    )
    assert "-> [-2" not in log  # never applied
    assert "internal error" not in log and "Traceback" not in log
    assert code == 0, log[-3000:]  # the pick-up went on to its grasp
