"""Reading YAML files node by node so that every error names its line (``FILE:LINE: error:``).

``yaml.compose`` keeps each node's position; these helpers check a node's shape and raise
:class:`SpotError` (line + message) that the file readers turn into ``UserError``.
"""

from __future__ import annotations

import math
from pathlib import Path

import yaml

from umbra.connectors import safe_yaml, user_files


class SpotError(Exception):
    """A problem at one line of a user's file."""

    def __init__(self, line: int, message: str) -> None:
        super().__init__(message)
        self.line = line
        self.message = message

    @classmethod
    def at(cls, node: yaml.Node, message: str) -> SpotError:
        return cls(node.start_mark.line + 1, message)


def compose(text: str, source: str) -> yaml.Node | None:
    """The node tree of YAML ``text`` (bounded depth and aliases, no duplicate keys); every
    problem becomes ``UserError`` with the line (``umbra.connectors.safe_yaml``)."""
    return safe_yaml.compose(text, source)


def read_text(path: str | Path, what: str) -> str:
    """A user's text file (a regular file of bounded size, UTF-8), or ``UserError`` saying why it
    cannot be read (``umbra.connectors.user_files``)."""
    return user_files.read_text(path, what)


def mapping(
    node: yaml.Node, what: str, required: tuple[str, ...], optional: tuple[str, ...] = ()
) -> dict[str, yaml.Node]:
    """Keys of a mapping node, checking required and allowed keys."""
    if not isinstance(node, yaml.MappingNode):
        keys = ", ".join(required + optional)
        raise SpotError.at(node, f"{what} must be a mapping with keys {keys}")
    found: dict[str, yaml.Node] = {}
    for key, value in node.value:
        name = key.value if isinstance(key, yaml.ScalarNode) else str(key)
        if name not in required and name not in optional:
            expected = ", ".join(required + optional)
            raise SpotError.at(key, f"unknown key {name!r} in {what}; expected {expected}")
        if name in found:
            raise SpotError.at(key, f"duplicate key {name!r} in {what}")
        found[name] = value
    missing = [k for k in required if k not in found]
    if missing:
        raise SpotError.at(node, f"{what} is missing {', '.join(repr(k) for k in missing)}")
    return found


def named_mapping(node: yaml.Node, what: str) -> list[tuple[str, yaml.Node, yaml.Node]]:
    """``(name, key node, value node)`` of a mapping with free-form names."""
    if not isinstance(node, yaml.MappingNode) or not node.value:
        raise SpotError.at(node, f"{what} must be a non-empty mapping of names")
    out = []
    seen: set[str] = set()
    for key, value in node.value:
        name = text(key, f"a name in {what}")
        if name in seen:
            raise SpotError.at(key, f"duplicate name {name!r} in {what}")
        seen.add(name)
        out.append((name, key, value))
    return out


def sequence(node: yaml.Node, what: str) -> list[yaml.Node]:
    """Items of a non-empty sequence node."""
    if not isinstance(node, yaml.SequenceNode) or not node.value:
        raise SpotError.at(node, f"{what} must be a non-empty list")
    return list(node.value)


def text(node: yaml.Node, what: str) -> str:
    """A scalar node's text."""
    if not isinstance(node, yaml.ScalarNode):
        raise SpotError.at(node, f"{what} must be text")
    return str(node.value)


def number(node: yaml.Node, what: str) -> float:
    """A scalar node as a finite float."""
    if not isinstance(node, yaml.ScalarNode):
        raise SpotError.at(node, f"{what} must be a number")
    try:
        value = float(node.value)
    except ValueError:
        raise SpotError.at(node, f"bad number {node.value!r} for {what}") from None
    if not math.isfinite(value):
        raise SpotError.at(node, f"bad number {node.value!r} for {what} (must be finite)")
    return value


def numbers(node: yaml.Node, what: str, count: int) -> list[float]:
    """A flow or block list of exactly ``count`` numbers."""
    if not isinstance(node, yaml.SequenceNode) or len(node.value) != count:
        found = len(node.value) if isinstance(node, yaml.SequenceNode) else "not a list"
        raise SpotError.at(node, f"{what} must be a list of {count} numbers, found {found}")
    return [number(item, what) for item in node.value]
