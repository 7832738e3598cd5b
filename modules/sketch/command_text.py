"""The text commands of the Sketch module (from the console, the CLI or a scripted operator).

One command per ``Text`` message; numbers are SI (metres, radians unless ``_deg``), pixels are
``u,v``. Grammar::

    aim X Y Z [ZOOM]             slew both PTUs to watch the point (m, base); optional zoom 0..1
    zoom Z                       both cameras' zoom, 0 (wide) .. 1 (tele)
    snapshot                     take a stereo snapshot pair
    place KIND U,V ... | U,V ... a primitive by its vertices in image a | image b
    plan MACRO [ID] [KEY=VALUE ...]   plan and check a macro for primitive ID (none: canned)
    vcr ACTION [NUMBER]          play / back / resume [SPEED], speed SPEED (0.1 .. 1),
                                 seek S (path units), pause, stop

:func:`parse` returns a :class:`Command` or raises ``UserError`` saying what was expected.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from umbra.connectors import UserError
from umbra.connectors.path_messages import VcrAction
from umbra.connectors.sketch_messages import Macro
from umbra.modules.sketch.macros import MacroError, macro_named
from umbra.modules.sketch.primitives import KINDS
from umbra.modules.trajectory.vcr import ACTIONS as VCR_ACTIONS
from umbra.modules.trajectory.vcr import ARGUMENT, VcrError, check_command

VERBS = ("aim", "zoom", "snapshot", "place", "plan", "vcr")


@dataclass
class Command:
    """A parsed command: ``verb`` and its arguments."""

    verb: str
    point: np.ndarray | None = None
    zoom: float | None = None
    kind: str = ""
    pixels_a: np.ndarray | None = None
    pixels_b: np.ndarray | None = None
    macro: Macro | None = None
    primitive_id: str = ""
    options: dict[str, float] = field(default_factory=dict)
    action: VcrAction | None = None
    speed: float | None = None
    s: float | None = None


def _numbers(words: list[str], what: str, text: str) -> list[float]:
    try:
        values = [float(w) for w in words]
    except ValueError:
        raise UserError(
            f"sketch command {text!r}: expected numbers for {what}, got {words}"
        ) from None
    if not all(np.isfinite(values)):
        raise UserError(f"sketch command {text!r}: {what} must be finite, got {values}")
    return values


def _pixels(words: list[str], text: str) -> np.ndarray:
    out = []
    for w in words:
        parts = w.split(",")
        if len(parts) != 2:
            raise UserError(f"sketch command {text!r}: expected pixels as u,v, got {w!r}")
        out.append(_numbers(parts, "a pixel", text))
    return np.asarray(out, dtype=float).reshape(-1, 2)


def parse(text: str) -> Command:
    """Parse one command (see module docstring)."""
    words = text.split()
    if not words or words[0] not in VERBS:
        raise UserError(f"sketch command {text!r}: expected one of {', '.join(VERBS)}")
    verb, rest = words[0], words[1:]
    if verb == "aim":
        values = _numbers(rest, "aim X Y Z [ZOOM]", text)
        if len(values) not in (3, 4) or (len(values) == 4 and not 0.0 <= values[3] <= 1.0):
            raise UserError(
                f"sketch command {text!r}: expected aim X Y Z [ZOOM] with 0 <= ZOOM <= 1"
            )
        return Command(
            verb, point=np.array(values[:3]), zoom=values[3] if len(values) > 3 else None
        )
    if verb == "zoom":
        values = _numbers(rest, "zoom Z", text)
        if len(values) != 1 or not 0.0 <= values[0] <= 1.0:
            raise UserError(f"sketch command {text!r}: expected zoom Z with 0 <= Z <= 1")
        return Command(verb, zoom=values[0])
    if verb == "snapshot":
        return Command(verb)
    if verb == "place":
        if not rest or rest[0] not in KINDS or "|" not in rest:
            raise UserError(
                f"sketch command {text!r}: expected place KIND U,V ... | U,V ... with KIND one of "
                f"{', '.join(KINDS)}"
            )
        bar = rest.index("|")
        return Command(
            verb,
            kind=rest[0],
            pixels_a=_pixels(rest[1:bar], text),
            pixels_b=_pixels(rest[bar + 1 :], text),
        )
    if verb == "plan":
        if not rest:
            raise UserError(f"sketch command {text!r}: expected plan MACRO [ID] [KEY=VALUE ...]")
        options = {}
        ident = ""
        for w in rest[1:]:
            if "=" in w:
                key, value = w.split("=", 1)
                options[key] = _numbers([value], key, text)[0]
            else:
                ident = w
        try:
            macro = macro_named(rest[0])
        except MacroError as error:
            raise UserError(f"sketch command {text!r}: {error}") from None
        return Command(verb, macro=macro, primitive_id=ident, options=options)
    if not rest or rest[0] not in VCR_ACTIONS:
        raise UserError(
            f"sketch command {text!r}: expected vcr ACTION [NUMBER] with ACTION one of "
            f"{', '.join(VCR_ACTIONS)}"
        )
    action = VcrAction(rest[0])
    values = _numbers(rest[1:], f"vcr {action}", text)
    takes = ARGUMENT[action]
    if len(values) > bool(takes) or (action in (VcrAction.SPEED, VcrAction.SEEK) and not values):
        what = {VcrAction.SEEK: " S", VcrAction.SPEED: " SPEED"}.get(
            action, " [SPEED]" if takes else ""
        )
        raise UserError(f"sketch command {text!r}: expected vcr {action}{what}")
    speed = values[0] if values and takes == "speed" else None
    s = values[0] if values and takes == "s" else None
    try:
        check_command(action, speed, s)
    except VcrError as exc:
        raise UserError(f"sketch command {text!r}: {exc}") from None
    return Command(verb, action=action, speed=speed, s=s)
