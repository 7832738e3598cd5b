"""The Foxglove WebSocket protocol's messages, as the live server sends and reads them (pure).

The protocol (``foxglove.websocket.v1``, named ``foxglove.sdk.v1`` by Foxglove's SDK: the same
protocol) is JSON text messages with an ``op`` field, and binary messages whose first byte is an
opcode. The server sends ``serverInfo`` on connection, ``advertise`` / ``unadvertise`` for its
channels, ``status``, ``parameterValues`` and binary *message data*
(``0x01``, subscription id ``u32``, log time ``u64`` [ns since the epoch], payload, little
endian); a client sends ``subscribe`` / ``unsubscribe``, ``getParameters`` / ``setParameters``.
Only what a read-and-tune viewer needs is spoken: no client publishing, services or assets.
"""

from __future__ import annotations

import base64
import json
import struct
from dataclasses import dataclass
from typing import Any

from umbra.connectors.json_text import json_text

#: Subprotocols served, the server's preference first (the same protocol under both names).
SUBPROTOCOLS = ("foxglove.sdk.v1", "foxglove.websocket.v1")
#: Capabilities advertised: parameters a viewer may read (and set those declared tunable).
CAPABILITIES = ("parameters",)
#: Binary opcode of a message-data frame.
MESSAGE_DATA = 0x01
_DATA_HEAD = struct.Struct("<BIQ")
#: ``status`` levels.
INFO, WARNING, ERROR = 0, 1, 2


@dataclass(frozen=True)
class ChannelInfo:
    """One channel as advertised: ``schema`` is the raw schema bytes (a protobuf
    FileDescriptorSet, or a JSON schema's UTF-8 text)."""

    id: int
    topic: str
    encoding: str
    schema_name: str
    schema_encoding: str
    schema: bytes

    def advertised(self) -> dict[str, Any]:
        """The channel's entry in an ``advertise`` message (binary schemas in base64)."""
        text = (
            self.schema.decode("utf-8")
            if self.schema_encoding in ("jsonschema", "json")
            else base64.b64encode(self.schema).decode("ascii")
        )
        return {
            "id": self.id,
            "topic": self.topic,
            "encoding": self.encoding,
            "schemaName": self.schema_name,
            "schema": text,
            "schemaEncoding": self.schema_encoding,
        }


def server_info(name: str, session_id: str) -> str:
    return json.dumps(
        {
            "op": "serverInfo",
            "name": name,
            "capabilities": list(CAPABILITIES),
            "metadata": {},
            "sessionId": session_id,
        }
    )


def advertise(channels: list[ChannelInfo]) -> str:
    return json.dumps({"op": "advertise", "channels": [c.advertised() for c in channels]})


def status(level: int, message: str) -> str:
    return json.dumps({"op": "status", "level": level, "message": message})


def parameter_values(parameters: list[dict[str, Any]], request_id: str | None) -> str:
    """``parameters``: ``{"name": ..., "value": ...}`` entries."""
    found: dict[str, Any] = {"op": "parameterValues", "parameters": parameters}
    if request_id is not None:
        found["id"] = request_id
    return json_text(found)


def message_data(subscription_id: int, log_time_ns: int, payload: bytes) -> bytes:
    """A binary message-data frame."""
    return _DATA_HEAD.pack(MESSAGE_DATA, subscription_id, log_time_ns) + payload


def read_request(text: str) -> dict[str, Any]:
    """A client's JSON message; ``ValueError`` naming what is wrong when it is not an object
    with a string ``op``."""
    try:
        found = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"expected a JSON object, found invalid JSON ({exc.msg})") from None
    if not isinstance(found, dict) or not isinstance(found.get("op"), str):
        raise ValueError("expected a JSON object with a string `op`")
    return found


def subscriptions(request: dict[str, Any]) -> list[tuple[int, int]]:
    """``(subscription id, channel id)`` pairs of a ``subscribe`` request."""
    found = []
    for item in _list(request, "subscriptions"):
        if not isinstance(item, dict):
            raise ValueError("expected `subscriptions` entries {id, channelId}")
        found.append((_uint(item.get("id"), "id"), _uint(item.get("channelId"), "channelId")))
    return found


def subscription_ids(request: dict[str, Any]) -> list[int]:
    return [_uint(i, "subscriptionIds") for i in _list(request, "subscriptionIds")]


def parameter_names(request: dict[str, Any]) -> list[str]:
    names = _list(request, "parameterNames", default=[])
    if not all(isinstance(n, str) for n in names):
        raise ValueError("expected `parameterNames` as a list of strings")
    return names


def parameter_changes(request: dict[str, Any]) -> list[tuple[str, Any]]:
    """``(name, value)`` of a ``setParameters`` request."""
    found = []
    for item in _list(request, "parameters"):
        if not isinstance(item, dict) or not isinstance(item.get("name"), str):
            raise ValueError("expected `parameters` entries {name, value}")
        found.append((item["name"], item.get("value")))
    return found


def request_id(request: dict[str, Any]) -> str | None:
    given = request.get("id")
    return given if isinstance(given, str) else None


def _list(request: dict[str, Any], key: str, default: list[Any] | None = None) -> list[Any]:
    found = request.get(key, default)
    if not isinstance(found, list):
        raise ValueError(f"expected `{key}` as a list, found {type(found).__name__}")
    return found


def _uint(value: Any, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < 2**32:
        raise ValueError(f"expected `{what}` as an integer in [0, 2^32), found {value!r}")
    return value
