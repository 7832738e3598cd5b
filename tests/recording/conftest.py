"""A recorded pick-up (sim clock, raw images) shared by the recording and replay tests, with the
samples the run produced, caught on the ports themselves (not read from the recording)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

from umbra.runtime.graph.check import load_graph
from umbra.runtime.graph.plan import GraphPlan
from umbra.runtime.scheduler import Scheduler, SchedulerOptions
from umbra.runtime.stats import RunResult

GRAPH = Path(__file__).with_name("pickup_small.yaml")
#: Long enough for the click, the snake's lock and some approach; short enough to stay fast.
DURATION = 1.5
WATCHED = [
    ("camera", "image"),
    ("snake", "contour"),
    ("world", "camera_pose"),
    ("servo", "twist"),
    ("register", "twist"),
    ("kinematics", "joint_rates"),
    ("kinematics", "link_poses"),
    ("kinematics", "tool_pose"),
    ("joints", "joint_state"),
]


@dataclass
class Run:
    """A finished run: folder, result, and what the watched ports sent (tick time, sample)."""

    out: Path
    result: RunResult
    plan: GraphPlan
    sent: dict[str, list[tuple[float, Any]]] = field(default_factory=dict)

    @property
    def recording(self) -> Path:
        return self.out / "recording.mcap"


def run_graph(
    plan: GraphPlan, out: Path, duration: float = DURATION, watched: list[tuple[str, str]] = WATCHED
) -> Run:
    """Run ``plan`` in one process on the sim clock, catching what the ``watched`` ports send."""
    scheduler = Scheduler(plan, SchedulerOptions(clock="sim", duration=duration, output_dir=out))
    run = Run(out, None, plan)  # type: ignore[arg-type]
    for module, port in watched:
        if module not in scheduler.modules:
            continue
        caught = run.sent.setdefault(f"{module}.{port}", [])

        def catch(sample: Any, now: float, caught: list = caught) -> None:
            caught.append((now, sample))

        scheduler.modules[module].outputs[port].sinks.insert(0, catch)
    out.mkdir(parents=True, exist_ok=True)
    run.result = scheduler.run()
    return run


def recorded_plan(images: str = "raw", **overrides: dict[str, Any]) -> GraphPlan:
    plan = load_graph(GRAPH, overrides=overrides or None)
    plan.spec.record.enabled = True
    plan.spec.record.images = images
    return plan


@pytest.fixture(scope="session")
def pickup_run(tmp_path_factory: pytest.TempPathFactory) -> Run:
    """The pick-up recorded with raw images, and what its ports sent."""
    run = run_graph(recorded_plan("raw"), tmp_path_factory.mktemp("pickup") / "run")
    assert run.result.reason.startswith(f"duration {DURATION:g} s reached"), run.result.reason
    return run
