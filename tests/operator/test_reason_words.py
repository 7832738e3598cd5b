"""The operator's words come from reason codes declared beside them, never from another module's
sentences: every code has words, and rewording a module's exact reason leaves the station's words
as they were (the exact text stays one click away)."""

from __future__ import annotations

import msgspec
import numpy as np
import pytest

from umbra.connectors.messages import registered_message_types
from umbra.connectors.reasons import Worded, missing_words, worded_enums
from umbra.connectors.states import GuardReason, GuardStage, GuardState, ServoReason, ServoStage
from umbra.connectors.tracking import SnakeCheck, TrackStatus
from umbra.modules.operator.jog import JogStop
from umbra.modules.operator.state_line import RUNNING, state_line
from umbra.modules.servo.vsservo import VsServo
from umbra.modules.vision.contour_message import contour_message
from umbra.modules.vision.features import polygon_features
from umbra.modules.vision.sanity import SanityLimits, check_contour
from umbra.runtime.harness import ModuleHarness


def _reason_enums() -> list[type[Worded]]:
    registered_message_types()  # imports every module of message types, and their codes
    return worded_enums()


def test_every_reason_code_has_operator_words() -> None:
    enums = _reason_enums()
    assert {GuardReason, ServoReason, SnakeCheck, JogStop} <= set(enums)
    missing = [name for codes in enums for name in missing_words(codes)]
    assert missing == [], "give each code its operator words beside it: NAME = 'code', 'words'"


def test_a_code_without_words_is_found() -> None:
    class Probe(Worded):
        SAID = "said", "said in plain words"
        UNSAID = "unsaid"

    assert missing_words(Probe) == ["Probe.UNSAID"]
    assert Probe.UNSAID == "unsaid" and Probe.SAID.words == "said in plain words"


def _rectangle(u0: float, v0: float, w: float, h: float, n: int = 8) -> np.ndarray:
    """A rectangle's outline [px] with ``n`` vertices per side."""
    t = np.linspace(0.0, 1.0, n, endpoint=False)
    top = np.c_[u0 + w * t, np.full(n, v0)]
    right = np.c_[np.full(n, u0 + w), v0 + h * t]
    bottom = np.c_[u0 + w * (1 - t), np.full(n, v0 + h)]
    left = np.c_[np.full(n, u0), v0 + h * (1 - t)]
    return np.vstack([top, right, bottom, left])


def _failed_contour() -> tuple[msgspec.Struct, tuple[SnakeCheck, ...]]:
    """A contour that jumped 100 px and shrank by half in one frame, as the real checks say
    it."""
    before = _rectangle(300, 200, 80, 60)
    after = _rectangle(420, 220, 56, 42)
    result = check_contour(after, SanityLimits(), previous=polygon_features(before))
    assert result.status == TrackStatus.FAILED
    message = contour_message(
        after, result.features, result.status, result.reason, 0.0, result.offending, result.checks
    )
    return message, result.checks


def _station_words(contour: msgspec.Struct) -> tuple[str, str]:
    """What the station's state line says of the grab vsServo stops on ``contour``: the plain
    words and the exact text behind them."""
    with ModuleHarness(VsServo) as h:
        h.push("contour", contour)
        state = h.step(0.02)["status"][0]
    assert state.stage == ServoStage.ASSIST and state.code == ServoReason.SNAKE_FAILED
    line = state_line(RUNNING, state, None, None, "ann", jogging=False)
    return line.stopped, line.stopped_detail


def test_reworded_reasons_leave_the_stations_words_as_they_were() -> None:
    contour, checks = _failed_contour()
    assert checks == (SnakeCheck.CENTROID_JUMP, SnakeCheck.AREA_CHANGE)
    words, exact = _station_words(contour)
    assert words == "the patch jumped in the image; the patch's size jumped"
    assert exact.startswith("snake failure: centroid jumped 1")  # with its figures, a click away
    assert "% in one frame" in exact
    reworded = msgspec.structs.replace(contour, reason="Schwerpunkt gesprungen; Fläche halbiert")
    words_after, exact_after = _station_words(reworded)
    assert words_after == words
    assert exact_after == "snake failure: Schwerpunkt gesprungen; Fläche halbiert"


@pytest.mark.parametrize("code", list(GuardReason))
def test_the_guards_words_are_its_codes_own(code: GuardReason) -> None:
    """The state line says a held arm's reason in the code's words, whatever the exact text."""
    if code == GuardReason.PASSING:
        return
    guard = GuardState(stage=GuardStage.ZERO, code=code, reason="any text at all (0.123 s)")
    line = state_line(RUNNING, None, guard, None, "ann", jogging=False)
    assert line.stopped == code.words and line.stopped_detail == "any text at all (0.123 s)"
