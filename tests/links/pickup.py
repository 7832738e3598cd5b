"""The split pick-up (graphs/tool_pickup.yaml) watched on its servo side, for the attack tests."""

from __future__ import annotations

import json
from pathlib import Path

from tests.links.conftest import REPO

PICKUP = REPO / "graphs" / "tool_pickup.yaml"
#: Key of the command link the attacks aim at: vsServo's twist into REG_VEL.
TWIST_KEY = "umbra/tool_pickup/servo/twist"
#: Servo period of the pick-up [s] (REG_VEL, WOLVERINE_JNTS and the ArmWatch run at 100 Hz).
PERIOD = 0.01


def pickup_with_watch(folder: Path) -> str:
    """Write the pick-up graph plus an ArmWatch (100 Hz, process `smart`) on the joints and the
    guard's status into ``folder``; the file's name. The console goes back into `umbra` (the
    attacks are on the links between vision and servo), so the two processes a test starts by
    hand are the whole graph (`ui` is left without modules)."""
    text = PICKUP.read_text()
    assert text.count("process: ui") == 1
    text = text.replace("process: ui", "process: umbra")
    watch = "  arm: {type: ArmWatch, process: smart, rate: 100}\n"
    assert text.count("\nconnections:\n") == 1
    text = text.replace("\nconnections:\n", f"\n{watch}connections:\n")
    text += "  - joints.joint_state -> arm.joints\n  - register.status -> arm.guard\n"
    (folder / "pickup.yaml").write_text(text)
    return "pickup.yaml"


def summary(folder: Path, process: str) -> dict:
    return json.loads((folder / f"summary-{process}.json").read_text())


def module(summary: dict, name: str) -> dict:
    return next(m for m in summary["modules"] if m["module"] == name)


def link(summary: dict, key: str) -> dict:
    return next(s for s in summary["links"]["subscribe"] if s["key"] == key)


def gaps_within(arm: dict, start: float, end: float) -> float:
    """The longest gap between two servo ticks [s] that ended within ``[start, end]``."""
    return max((gap for at, gap in arm["long_gaps"] if start <= at <= end), default=0.0)
