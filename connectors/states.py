"""Typed states that modules decide on: the safety guard's, the grab's, the console's presence.

Each state says where its producer is with an enum (``stage``), why with a reason code (``code``,
a :class:`~umbra.connectors.reasons.Worded` enum carrying the operator's words) and the exact
text for logs (``reason``: figures included, free to change: no module reads it). ``umbra check``
tells them apart: a :class:`GuardState` is not a :class:`ServoState`, and a free-text
:class:`~umbra.connectors.messages.Status` is neither. A :class:`ServoState` is a ``Status`` (a
status for a person: ``message``, ``assist``, figures in ``values``), so a display that takes any
status (a plot, the video overlay, the 3-D page's state line) takes it too.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from umbra.connectors.messages import Message, Status
from umbra.connectors.reasons import Code, Worded, words_of
from umbra.connectors.tracking import SnakeCheck

#: An age [s] that cannot be told (no command yet, undatable data) is sent as this.
NO_AGE_S = 1e9

_F8 = "float64"


class GuardStage(Code):
    """Whether the safety guard (REG_VEL) passes its command or holds the arm at zero."""

    PASSING = "passing"
    ZERO = "zero"


class GuardReason(Worded):
    """Why the guard passes or holds the arm at zero."""

    PASSING = "passing", "commands pass"
    NO_COMMAND_YET = "no_command_yet", "no command yet"
    WATCHDOG = "watchdog", "commands stopped arriving in time"
    STALE_DATA = "stale_data", "the camera data behind the command is too old"
    UNDATABLE = "undatable", "the camera data cannot be dated"
    PRODUCER_GONE = "producer_gone", "the vision process is gone"
    REJECTED = "rejected", "a malformed command was refused"
    WRONG_FRAME = "wrong_frame", "the command came in another frame than the guard's"
    HALTED = "halted", "the grab stopped and asks for you"


class GuardState(Message, frozen=True, kw_only=True):
    """The safety guard's state: passing or at zero, why, the ages of the command it judges and
    the travel it let through (its odometer, in its ``frame`` parameter's frame)."""

    #: What each field holds on the wire (unit, dtype and shape): ``docs/wire-format.md``.
    FIELD_NOTES: ClassVar[dict[str, str]] = {
        "stage": '"passing" or "zero"',
        "code": "why (GuardReason): " + ", ".join(f'"{m}"' for m in GuardReason),
        "reason": "the exact reason, for logs (empty while passing)",
        "jog": "true: the output is the operator's jog (passing it, or its zero)",
        "age_s": f"s since the command arrived ({NO_AGE_S:g}: none)",
        "origin_age_s": f"s, age of the sensor data the command was made from ({NO_AGE_S:g}: "
        "none, or cannot be dated)",
        "stale": "true: at zero because the data behind the command is too old",
        "travel_m": f"{_F8} (3,), m: linear travel let through so far, in the guard's frame",
    }

    stage: GuardStage
    code: GuardReason
    reason: str = ""
    jog: bool = False
    age_s: float = NO_AGE_S
    origin_age_s: float = NO_AGE_S
    stale: bool = False
    travel_m: np.ndarray = np.zeros(3)

    @property
    def passing(self) -> bool:
        """True when the guard passes its command (or the jog)."""
        return self.stage == GuardStage.PASSING


class ServoStage(Code):
    """The stages of a visual-servo grab (vsServo)."""

    ACQUIRE = "acquire"
    APPROACH = "approach"
    FINAL_GRAB = "final_grab"
    DONE = "done"
    ASSIST = "assist"
    ABORTED = "aborted"
    PAUSED = "paused"


class ServoReason(Worded):
    """Why the grab waits, stopped or asks for the operator."""

    NONE = "none", "nothing stops the grab"
    NO_CONTOUR = "no_contour", "the tracker sends nothing"
    NOT_SEEDED = "not_seeded", "no patch seeded yet: click the patch"
    CONTOUR_LATE = "contour_late", "the tracker's outline came too late"
    SNAKE_FAILED = "snake_failed", "the tracker failed"
    NO_FEATURES = "no_features", "the patch's outline cannot be measured"
    PAUSED = "paused", "paused by the operator"
    ABORTED = "aborted", "aborted by the operator"


class ServoState(Status, frozen=True, kw_only=True):
    """The grab's state (vsServo): ``stage``, why (``code``, and the tracker's failed ``checks``
    when the snake failed; ``reason`` the exact text), what it is doing for a person
    (``message``), whether it asks for the operator (``assist``), and its errors in ``values``
    (``error_x``, ``error_y``, ``error_z`` [m], ``error_roll`` [rad], camera frame; those not
    measured are left out)."""

    #: What each field holds on the wire (unit, dtype and shape): ``docs/wire-format.md``.
    FIELD_NOTES: ClassVar[dict[str, str]] = {
        "stage": "ServoStage: " + ", ".join(f'"{m}"' for m in ServoStage),
        "message": "what the grab is doing, for a person",
        "assist": "true: the operator's help is requested",
        "reason": "the exact reason, for logs (empty: none)",
        "values": "map str -> float: error_x, error_y, error_z (m), error_roll (rad), "
        "camera frame, those measured",
        "code": "why (ServoReason): " + ", ".join(f'"{m}"' for m in ServoReason),
        "checks": "the tracker's failed checks (SnakeCheck), when `code` is snake_failed",
    }

    stage: ServoStage
    code: ServoReason = ServoReason.NONE
    checks: tuple[SnakeCheck, ...] = ()

    def words(self) -> str:
        """Why, in the operator's words: the failed checks' words when the tracker failed on
        named checks, else the code's."""
        if self.code == ServoReason.SNAKE_FAILED and self.checks:
            return words_of(self.checks)
        return self.code.words


class Outcome(Code):
    """What a judge of the run decided: nothing yet, success, a miss, a stop before success
    (the operator's *Stop*, an assistance request nobody answered, data too old to go on), or
    done: played to its end, with nothing to judge (an Active Sketch macro such as ``ready``)."""

    PENDING = "pending"
    SUCCEEDED = "succeeded"
    MISSED = "missed"
    STOPPED = "stopped"
    DONE = "done"


class Verdict(Status, frozen=True, kw_only=True):
    """A judge's verdict on the run (a simulated world's): ``stage`` names what was judged (the
    world's state, a macro), ``message`` the verdict in words, ``values`` its figures and
    ``outcome`` the decision as a code, which is what other modules read."""

    #: What each field holds on the wire (unit, dtype and shape): ``docs/wire-format.md``.
    FIELD_NOTES: ClassVar[dict[str, str]] = {
        "stage": "what was judged: the world's state, or a macro",
        "message": "the verdict in words",
        "assist": "true: the operator's help is requested",
        "reason": "why help is requested",
        "values": "map str -> float: the verdict's figures",
        "outcome": "Outcome: " + ", ".join(f'"{m}"' for m in Outcome),
    }

    outcome: Outcome = Outcome.PENDING


class Presence(Message, frozen=True, kw_only=True):
    """Who is at the operator's console: whether a person holds control, whether a person has
    acted this run (a simulated operator then steps aside), and how many pages are open."""

    #: What each field holds on the wire (unit, dtype and shape): ``docs/wire-format.md``.
    FIELD_NOTES: ClassVar[dict[str, str]] = {
        "person": "true: a person holds control",
        "acted": "true: a person has acted on the console this run",
        "viewers": "pages open",
        "holder": "the name of the page holding control (empty: nobody)",
    }

    person: bool = False
    acted: bool = False
    viewers: int = 0
    holder: str = ""
