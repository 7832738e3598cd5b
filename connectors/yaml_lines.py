"""Line numbers of the parts of a YAML document, by key path — for ``FILE:LINE: error:`` messages
of the small YAML files modules read (DH tables, drive configurations)."""

from __future__ import annotations

import yaml

KeyPath = tuple[str | int, ...]


def node_lines(
    node: yaml.Node, path: KeyPath = (), lines: dict[KeyPath, int] | None = None
) -> dict[KeyPath, int]:
    """``{key path: 1-based line}`` for every mapping key and list item under ``node``."""
    lines = {} if lines is None else lines
    lines[path] = node.start_mark.line + 1
    if isinstance(node, yaml.MappingNode):
        for key, value in node.value:
            child = (*path, key.value)
            node_lines(value, child, lines)
            lines[child] = key.start_mark.line + 1
    elif isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            node_lines(item, (*path, i), lines)
    return lines
