"""``session.json`` of ``umbra sketch``, read against a typed schema before anything replays it.

The file is the user's (it may be hand-edited): it is read bounded and decoded as UTF-8
(:mod:`umbra.connectors.user_files`), then decoded by msgspec into :class:`SessionState`, whose
events are a union tagged by ``cmd`` with every field typed and ranged as the command line
checks it (a seed is a whole number >= 0, a zoom 0..1, click noise 0..20 px, a play timeout
0..3600 s, script steps ``[time >= 0, VCR action, number or null]``). Unknown commands, unknown or
missing keys, wrong types, non-finite numbers and deep nesting are each one
``FILE[:LINE]: error: ...`` (:class:`~umbra.connectors.errors.UserError`, exit status 2), never a
traceback.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Annotated, Any

import msgspec

from umbra.connectors.errors import UserError
from umbra.connectors.limits import MAX_SKETCH_SESSION_BYTES as MAX_SESSION_BYTES
from umbra.connectors.limits import MAX_SKETCH_SESSION_EVENTS as MAX_SESSION_EVENTS
from umbra.connectors.path_messages import VcrAction
from umbra.connectors.sketch_messages import PrimitiveKind
from umbra.connectors.user_files import decode_text, read_bytes
from umbra.modules.trajectory.vcr import ACTIONS as VCR_ACTIONS

#: Largest coordinate or option value kept in a session (a bound, not physics: finite numbers).
_BIG = 1e9

Finite = Annotated[float, msgspec.Meta(ge=-_BIG, le=_BIG)]
Name = Annotated[str, msgspec.Meta(max_length=200)]
_NUMBER = r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d{1,2})?"
#: A pixel as the command line takes it, ``U,V`` (finite numbers: no nan, no 1e999).
Pixel = Annotated[str, msgspec.Meta(max_length=100, pattern=f"^{_NUMBER},{_NUMBER}$")]


class _Event(msgspec.Struct, tag_field="cmd", forbid_unknown_fields=True):
    """A command given to the session (``cmd`` names it)."""


class Aim(_Event, tag="aim"):
    xyz: Annotated[list[Finite], msgspec.Meta(max_length=3)]
    at: Name | None
    zoom: Annotated[float, msgspec.Meta(ge=0.0, le=1.0)] | None


class Snapshot(_Event, tag="snapshot"):
    pass


class Place(_Event, tag="place"):
    kind: PrimitiveKind
    a: Annotated[list[Pixel], msgspec.Meta(max_length=16)]
    b: Annotated[list[Pixel], msgspec.Meta(max_length=16)]
    truth: Name | None
    noise: Annotated[float, msgspec.Meta(ge=0.0, le=20.0)]
    seed: Annotated[int, msgspec.Meta(ge=0, le=2**32)]


class Macros(_Event, tag="macros"):
    primitive: Name | None


class Plan(_Event, tag="plan"):
    macro: Name
    primitive: Name | None
    options: Annotated[dict[Name, Finite], msgspec.Meta(max_length=32)]


ScriptStep = tuple[Annotated[float, msgspec.Meta(ge=0.0, le=_BIG)], VcrAction, Finite | None]


class Play(_Event, tag="play"):
    path: Name
    script: Annotated[list[ScriptStep], msgspec.Meta(max_length=1000)]
    timeout: Annotated[float, msgspec.Meta(gt=0.0, le=3600.0)]


Event = Aim | Snapshot | Place | Macros | Plan | Play
#: The values a field of a choice may take, by field name (for the error that names them).
_CHOICES: dict[str, tuple[str, ...]] = {
    "cmd": tuple(str(e.__struct_config__.tag) for e in (Aim, Snapshot, Place, Macros, Plan, Play)),
    "kind": tuple(str(kind) for kind in PrimitiveKind),
    "script": VCR_ACTIONS,
}


class SessionState(msgspec.Struct, forbid_unknown_fields=True):
    """The whole file: the scene's seed and the commands given so far, in order."""

    seed: Annotated[int, msgspec.Meta(ge=0, le=2**32 - 1)]
    events: Annotated[list[Event], msgspec.Meta(max_length=MAX_SESSION_EVENTS)]


def parse_session_state(data: bytes, source: str) -> dict[str, Any]:
    """``{"seed": int, "events": [dict, ...]}`` from the bytes of a session file; UserError
    ``SOURCE[:LINE]: error: ...`` naming what was expected and where it was not found."""
    text = decode_text(data, source)
    try:
        state = msgspec.json.decode(text, type=SessionState)
    except msgspec.ValidationError as exc:
        raise UserError(f"{source}: error: {_plain(str(exc))}") from None
    except msgspec.DecodeError as exc:
        raise UserError(f"{source}{_line_of(str(exc), text)}: error: {exc}") from None
    except RecursionError:
        raise UserError(f"{source}: error: nested too deeply for a session file") from None
    for i, event in enumerate(state.events):
        if isinstance(event, Aim) and (event.at is None) == (len(event.xyz) != 3):
            raise UserError(
                f"{source}: error: expected `xyz` of 3 numbers or `at` (one of them) - at "
                f"`$.events[{i}]`"
            )
    out = msgspec.to_builtins(state)
    for event in out["events"]:
        if event["cmd"] == "play":
            event["script"] = [list(step) for step in event["script"]]
    return out


def load_session_state(path: Path) -> dict[str, Any]:
    """The session state in the file ``path`` (bounded read, typed decode; UserError)."""
    return parse_session_state(
        read_bytes(path, "sketch session file", MAX_SESSION_BYTES), str(path)
    )


def _plain(message: str) -> str:
    """msgspec's message, an unknown choice followed by the choices there are, a pattern in
    words."""
    pattern = re.match(r"Expected `str` matching regex '.*' - at (`[^`]*`)$", message)
    if pattern:
        return f"expected a pixel written U,V (finite numbers, like 320.5,240) - at {pattern[1]}"
    found = re.match(r"Invalid (?:enum )?value (.+) - at `(\$[^`]*)`$", message)
    if not found:
        return message
    names = re.findall(r"\.([a-z_]+)", found.group(2))
    choices = _CHOICES.get(names[-1] if names else "", ())
    expected = f" (expected one of {', '.join(choices)})" if choices else ""
    return f"unknown value {found.group(1)}{expected} - at `{found.group(2)}`"


def _line_of(message: str, text: str) -> str:
    """``:LINE`` of msgspec's ``(byte N)`` in a decode error, else empty."""
    marker = "(byte "
    if marker not in message:
        return ""
    try:
        byte = int(message[message.index(marker) + len(marker) :].split(")")[0])
    except ValueError:
        return ""
    prefix = text.encode("utf-8")[:byte].decode("utf-8", errors="ignore")
    return f":{prefix.count(chr(10)) + 1}"
