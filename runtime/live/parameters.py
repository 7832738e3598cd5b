"""The run's module parameters as a viewer sees them: ``MODULE.PARAM`` → value.

A viewer may read every parameter; a request to change one is refused with a message to that
viewer and a line in the run's log (the current value is the answer).
"""

from __future__ import annotations

import json
import logging
from typing import Any


def viewer_value(value: Any) -> Any:
    """A parameter value as the protocol carries it (numbers, strings, bools, lists of numbers;
    anything else as JSON text)."""
    if isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, (list, tuple)) and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) for v in value
    ):
        return [float(v) for v in value]
    return json.dumps(value, default=str)


class ParameterTable:
    """Every parameter of the run, read only (``runtime.live.viewer_server.ParameterHandler``)."""

    def __init__(self, values: dict[str, Any], log: logging.Logger | None = None) -> None:
        self._values = dict(values)
        self._log = log or logging.getLogger("umbra.foxglove")

    def get(self, names: list[str]) -> list[dict[str, Any]]:
        wanted = names or list(self._values)
        return [
            {"name": n, "value": viewer_value(self._values[n])} for n in wanted if n in self._values
        ]

    def set(self, viewer: str, changes: list[tuple[str, Any]]) -> tuple[list[str], list[str]]:
        names = [name for name, _ in changes]
        self._log.warning(
            "foxglove: viewer %s asked to set %s: refused (parameters are read only live)",
            viewer,
            ", ".join(names[:8]),
        )
        return names, [f"parameter `{n}` cannot be changed live (read only)" for n in names]
