"""One rule for a VCR command: the text command, a session's VCR script and the VCR itself
accept and refuse exactly the same actions, speeds and seek targets."""

from __future__ import annotations

import pytest

from umbra.connectors import UserError
from umbra.modules.sketch.command_text import parse
from umbra.modules.sketch.session import SessionError, _check_step
from umbra.modules.trajectory.vcr import ARGUMENT, Vcr, VcrError, VcrLimits

LENGTH = 2.0
LIMITS = VcrLimits.for_stop_time(rate=0.5, stop_time_s=0.25)
CASES = [
    ("play", None, None, True),
    ("play", 0.1, None, True),
    ("play", 0.1 - 1e-12, None, True),  # round-off at the end of the range: clipped
    ("back", 1.0 + 1e-12, None, True),
    ("resume", 0.5, None, True),
    ("play", 0.09, None, False),
    ("back", 1.01, None, False),
    ("speed", 0.3, None, True),
    ("speed", None, None, False),
    ("speed", 5.0, None, False),
    ("seek", None, 1.5, True),
    ("seek", None, 0.0, True),
    ("seek", None, -0.5, False),
    ("pause", None, None, True),
    ("stop", None, None, True),
    ("rewind", None, None, False),
]


def _verdicts(action: str, speed: float | None, s: float | None) -> dict[str, bool]:
    out = {}
    number = speed if speed is not None else s
    text = f"vcr {action}" + (f" {number!r}" if number is not None else "")
    try:
        parse(text)
        out["text"] = True
    except UserError:
        out["text"] = False
    kwargs = {k: v for k, v in (("speed", speed), ("s", s)) if v is not None}
    try:
        _check_step(0.0, action, kwargs, LENGTH)
        out["script"] = True
    except SessionError:
        out["script"] = False
    try:
        Vcr(LENGTH, LIMITS).command(action, speed=speed, s=s)
        out["vcr"] = True
    except VcrError:
        out["vcr"] = False
    return out


@pytest.mark.parametrize(("action", "speed", "s", "ok"), CASES)
def test_every_writer_of_a_vcr_command_applies_the_same_rule(action, speed, s, ok):
    verdicts = _verdicts(action, speed, s)
    assert verdicts == {"text": ok, "script": ok, "vcr": ok}, verdicts


def test_the_rule_knows_every_action_and_what_it_takes():
    assert set(ARGUMENT) == {"play", "back", "pause", "resume", "speed", "seek", "stop"}
    with pytest.raises(SessionError, match=r"0.0:pause: takes nothing, got \['speed'\]"):
        _check_step(0.0, "pause", {"speed": 0.5}, LENGTH)
    with pytest.raises(UserError, match=r"expected vcr pause$"):
        parse("vcr pause 0.5")
    with pytest.raises(VcrError, match=r"expected a seek target within 0 \.\. 2, got 3"):
        Vcr(LENGTH, LIMITS).command("seek", s=3.0)
