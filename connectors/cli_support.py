"""Helpers shared by CLI sub-commands, in the runtime and in domain packages."""

from __future__ import annotations

import math
import sys
from typing import Any

from umbra.connectors import safe_yaml
from umbra.connectors.errors import UserError
from umbra.connectors.json_text import json_text

#: Longest ``--set`` value [characters].
MAX_VALUE_CHARS = 10_000


def parse_value(text: str, where: str = "--set") -> Any:
    """A command-line value as a YAML scalar or flow collection (``3``, ``true``, ``[1, 2]``);
    text that is not YAML stays text. Bounded like every YAML the project reads: a value too long,
    too deep, an alias bomb, a duplicate key or a bad tagged value is a UserError naming ``where``.
    """
    if not text.strip():
        return ""
    if len(text) > MAX_VALUE_CHARS:
        raise UserError(
            f"{where}: error: value of {len(text)} characters, at most {MAX_VALUE_CHARS}"
        )
    try:
        return safe_yaml.load(text, where)[1]
    except safe_yaml.YamlError as exc:
        if exc.syntax:
            return text
        raise UserError(f"{where}: error: {exc.message}") from None


def parse_set(items: list[str] | None) -> dict[str, Any]:
    """``["a=1", "b=x"]`` -> ``{"a": 1, "b": "x"}``; UserError on a malformed item."""
    out: dict[str, Any] = {}
    for item in items or []:
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            raise UserError(f"--set expects NAME=VALUE, found `{item}`")
        out[name.strip()] = parse_value(value, f"--set {name.strip()}")
    return out


def parse_module_set(items: list[str] | None) -> dict[str, dict[str, Any]]:
    """``["snake.k=2"]`` -> ``{"snake": {"k": 2}}``; UserError on a malformed item."""
    out: dict[str, dict[str, Any]] = {}
    for name, value in parse_set(items).items():
        module, dot, param = name.partition(".")
        if not dot or not module or not param:
            raise UserError(f"--set expects MODULE.PARAM=VALUE, found `{name}=...`")
        out.setdefault(module, {})[param] = value
    return out


def print_json(obj: Any) -> None:
    """Print one JSON object on stdout (numpy values converted)."""
    sys.stdout.write(json_text(obj) + "\n")


def check_seconds(option: str, value: float | None, hint: str = "") -> None:
    """Refuse (``UserError``) a time span given on the command line that is not a positive,
    finite number of seconds; ``None`` (the option left out) passes. ``hint`` is added to the
    message in parentheses."""
    if value is None or (value > 0 and math.isfinite(value)):
        return
    extra = f" ({hint})" if hint else ""
    raise UserError(f"{option} must be a positive, finite number of seconds{extra}, found {value}")
