"""``umbra check`` tells a guard's state from a grab's state from a free-text status, and the
operator's commands and seeds from text and vectors: the pick-up graph with its state links
crossed is refused, each at its line, with what was sent and what was expected (exit 2)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
PICKUP = REPO / "graphs" / "tool_pickup.yaml"

#: (the pick-up's connection, the crossed one, the fault `umbra check` must name)
CROSSED = [
    (
        "  - register.status -> console.guard",
        "  - register.status -> console.servo",
        "`register.status` sends GuardState, `console.servo` expects ServoState",
    ),
    (
        "  - servo.status -> console.servo",
        "  - servo.status -> console.guard",
        "`servo.status` sends ServoState, `console.guard` expects GuardState",
    ),
    (
        "  - register.status ~> servo.guard",
        "  - joints.status ~> servo.guard",
        "`joints.status` sends Status, `servo.guard` expects GuardState",
    ),
    (
        "  - servo.status -> register.halt",
        "  - world.status -> register.halt",
        "`world.status` sends Verdict, `register.halt` expects ServoState",
    ),
    (
        "  - servo.gripper -> register.gripper_in",
        "  - console.operator -> register.gripper_in",
        "`console.operator` sends GrabCommand, `register.gripper_in` expects GripperCommand",
    ),
    (
        "  - console.seed ~> snake.seed",
        "  - console.presence ~> snake.seed",
        "`console.presence` sends Presence, `snake.seed` expects Seed",
    ),
]


def _check(path: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "umbra.runtime.cli.main", "check", str(path)],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=REPO,
    )


def test_crossed_state_links_are_type_errors_at_their_lines(tmp_path: Path) -> None:
    text = PICKUP.read_text()
    for line, crossed, _fault in CROSSED:
        assert text.count(line) == 1, f"the pick-up graph no longer has `{line.strip()}`"
        text = text.replace(line, crossed)
    graph = tmp_path / "crossed.yaml"
    graph.write_text(text)
    done = _check(graph)
    assert done.returncode == 2, done.stdout + done.stderr
    lines = text.splitlines()
    for _line, crossed, fault in CROSSED:
        number = next(i for i, text_line in enumerate(lines, 1) if text_line.startswith(crossed))
        assert f"{graph}:{number}:" in done.stderr and f"type mismatch: {fault}" in done.stderr, (
            fault,
            done.stderr,
        )
    assert "Traceback" not in done.stderr


def test_the_pickup_wires_each_state_to_the_input_that_wants_it() -> None:
    done = _check(PICKUP)
    assert done.returncode == 0, done.stderr
    for link in (
        "servo.status -> register.halt (ServoState",
        "servo.gripper -> register.gripper_in (GripperCommand",
        "register.status ~> servo.guard (GuardState",
    ):
        assert link in done.stdout + done.stderr, link
