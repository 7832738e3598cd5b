"""``umbra run graphs/tool_pickup.yaml --attended``: split over its three processes, the run
outlives its duration with nobody seeding, and Ctrl-C ends it (exit 130, summaries written)."""

from __future__ import annotations

import json
import signal
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from tests.links.conftest import REPO, Running
from umbra.connectors.states import Outcome

# a whole split pick-up in subprocesses, ~30 s: in CI with -m slow
pytestmark = pytest.mark.slow

DURATION_S = 2.0


def _module(summary: dict, name: str) -> dict:
    return next(m for m in summary["modules"] if m["module"] == name)


def test_attended_split_run_waits_for_its_operator_then_ctrl_c_ends_it(
    umbra: Callable[..., Running], tmp_path: Path
) -> None:
    graph = str(REPO / "graphs" / "tool_pickup.yaml")
    run = umbra("run", graph, "--attended", "--duration", str(DURATION_S), "--out", "out")
    run.wait_for("duration of 2 s is not applied", timeout=30)
    run.wait_for("`umbra`: links ready, running", timeout=60)
    run.wait_for("attended run: the simulated operator stays off", timeout=30)
    ready = time.monotonic()
    # OperatorSim would click after 3 s (its click_delay_s) and the graph would end after 2 s:
    # four times the duration later the run is alive and nobody has seeded
    time.sleep(4 * DURATION_S)
    assert run.popen.poll() is None, run.text
    assert "operator clicked the patch" not in run.text
    assert "finished" not in run.text
    run.popen.send_signal(signal.SIGINT)
    assert run.finish(timeout=60) == 130, run.text
    assert time.monotonic() - ready > 4 * DURATION_S
    out = tmp_path / "out"
    whole = json.loads((out / "summary.json").read_text())
    assert whole["exit_code"] == 130 and "interrupted by SIGINT" in whole["reason"]
    assert {p["process"] for p in whole["processes"]} == {"umbra", "ui", "smart"}
    umbra_side = json.loads((out / "summary-umbra.json").read_text())
    operator = _module(umbra_side, "operator")
    assert operator["attended"] is True and operator["clicked_after_s"] is None
    smart = json.loads((out / "summary-smart.json").read_text())
    assert smart["wall_time_s"] > 2 * DURATION_S  # the servo side ran well past its duration
    assert _module(smart, "world")["outcome"] == Outcome.PENDING
    # the world's status (running, later the verdict) reaches the page's process every second
    ui = json.loads((out / "summary-ui.json").read_text())
    world = next(sub for sub in ui["links"]["subscribe"] if sub["key"].endswith("/world/status"))
    assert world["received"] >= 4 * DURATION_S - 1
