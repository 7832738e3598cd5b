"""Messages from the page over its websocket: parsed, bounded and checked before anything acts.

Every message is one JSON object of at most :data:`MAX_MESSAGE_BYTES` with ``session`` (the
nonce the server gave this socket), ``seq`` (strictly increasing per socket; a repeat or an
older one is a replay) and ``type``. Anything else is refused with a message that says what was
expected and what was found. Pure: no I/O.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from typing import Any

from umbra.connectors.commands import GrabAction
from umbra.connectors.limits import MAX_PAGE_MESSAGE_BYTES
from umbra.modules.operator.jog import JogFrame

MAX_MESSAGE_BYTES = MAX_PAGE_MESSAGE_BYTES  #: (the websocket protocol refuses larger ones first)
STOP_ACTION = "stop"  #: end the run (the judge ends it): the console's ``StopRun``
#: the page's actions: the grab's commands, and stop
ACTIONS = (*(str(a) for a in GrabAction), STOP_ACTION)
JOG_FRAMES = tuple(str(frame) for frame in JogFrame)

#: message type -> required fields and their kinds ("num" finite number, "int", "bool", "str")
_SCHEMA: dict[str, dict[str, str]] = {
    "hello": {"name": "str"},
    "take": {},
    "release": {},
    "click": {"u": "num", "v": "num", "frame": "int"},
    "box": {"u0": "num", "v0": "num", "u1": "num", "v1": "num", "frame": "int"},
    "action": {"action": "str"},
    "jog": {"held": "bool", "axes": "axes", "jog_frame": "str", "speed": "num", "frame": "int"},
    "painted": {"frame": "int", "latency_ms": "num"},
    "seen": {"state": "int"},  #: the page has drawn state ``version`` (and every one before)
    "zoom": {"camera": "str", "value": "num"},
}


class ProtocolError(ValueError):
    """A message the console refuses; ``str()`` is the message for the page and the log."""


class ReplayedMessage(ProtocolError):
    """A message of another page's session, or one whose ``seq`` is not new: a replay."""


@dataclass(frozen=True)
class ClientMessage:
    """A checked message: its ``type``, ``seq`` and fields."""

    type: str
    seq: int
    fields: dict[str, Any] = field(default_factory=dict)


def _kind_ok(kind: str, value: Any) -> bool:
    if kind == "num":
        return (
            isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
        )
    if kind == "int":
        return isinstance(value, int) and not isinstance(value, bool) and value >= 0
    if kind == "bool":
        return isinstance(value, bool)
    if kind == "str":
        return isinstance(value, str) and len(value) <= 64
    if kind == "axes":
        return (
            isinstance(value, list)
            and len(value) == 4
            and all(_kind_ok("num", a) and -1.0 <= a <= 1.0 for a in value)
        )
    return False


_KIND_TEXT = {
    "num": "a finite number",
    "int": "a non-negative integer",
    "bool": "true or false",
    "str": "a string of at most 64 characters",
    "axes": "4 numbers in [-1, 1] (x, y, z, roll)",
}


class MessageChecker:
    """Checks one socket's messages: size, JSON shape, session nonce, replay (seq order)."""

    def __init__(self, session: str) -> None:
        self.session = session
        self.last_seq = -1

    def check(self, raw: str | bytes) -> ClientMessage:
        """The checked message, or :class:`ProtocolError` naming what is wrong."""
        size = len(raw)
        if size > MAX_MESSAGE_BYTES:
            raise ProtocolError(
                f"malformed message: expected at most {MAX_MESSAGE_BYTES} bytes, found {size}"
            )
        try:
            data = json.loads(raw)
        except (ValueError, UnicodeDecodeError) as exc:
            raise ProtocolError(
                f"malformed message: expected JSON, found an error: {exc}"
            ) from None
        if not isinstance(data, dict):
            raise ProtocolError(
                f"malformed message: expected a JSON object, found {type(data).__name__}"
            )
        if data.get("session") != self.session:
            raise ReplayedMessage(
                "replayed message: expected this page's session, found "
                f"{str(data.get('session'))[:16]!r} (reload the page)"
            )
        seq = data.get("seq")
        if not isinstance(seq, int) or not _kind_ok("int", seq):
            raise ProtocolError(
                f"malformed message: expected seq {_KIND_TEXT['int']}, found {seq!r}"
            )
        if seq <= self.last_seq:
            raise ReplayedMessage(f"replayed message: expected seq > {self.last_seq}, found {seq}")
        kind = data.get("type")
        schema = _SCHEMA.get(kind) if isinstance(kind, str) else None
        if schema is None or not isinstance(kind, str):
            raise ProtocolError(
                f"malformed message: expected type one of {sorted(_SCHEMA)}, found {kind!r}"
            )
        fields: dict[str, Any] = {}
        for name, field_kind in schema.items():
            value = data.get(name)
            if not _kind_ok(field_kind, value):
                raise ProtocolError(
                    f"malformed {kind} message: expected {name} {_KIND_TEXT[field_kind]}, "
                    f"found {value!r}"[:200]
                )
            fields[name] = value
        if kind == "action" and fields["action"] not in ACTIONS:
            raise ProtocolError(
                f"malformed action: expected one of {list(ACTIONS)}, found {fields['action']!r}"
            )
        if kind == "jog" and fields["jog_frame"] not in JOG_FRAMES:
            raise ProtocolError(
                f"malformed jog: expected jog_frame one of {list(JOG_FRAMES)}, "
                f"found {fields['jog_frame']!r}"
            )
        if kind == "jog" and not 0.0 <= fields["speed"] <= 1.0:
            raise ProtocolError(f"malformed jog: expected speed in [0, 1], found {fields['speed']}")
        self.last_seq = seq
        return ClientMessage(kind, seq, fields)
