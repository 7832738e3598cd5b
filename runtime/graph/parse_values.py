"""The graph file's ``values:``: a value the graph knows once, named, and used where it is needed.

::

    values:
      wrist_fx: 800                 # [px]
      patch_size_m: [0.06, 0.04]
    modules:
      camera: {type: DigiCam, params: {fx: $wrist_fx, patch_size_m: $patch_size_m}}
      view3d: {type: View3D, params: {wrist_intrinsics: [$wrist_fx, $wrist_fx, 640, 360]}}

A text that is exactly ``$NAME`` (NAME an identifier), anywhere in the graph but in ``values:``
itself, is replaced by that value (a number, a text, a list or a mapping); ``$$NAME`` is the text
``$NAME``. The value keeps the location where ``values:`` writes it, so a value a module refuses
is reported there. A graph that extends another sees the base's values and may override them.
What the references expand to is bounded as YAML aliases are (``MAX_NODES`` in all).
``values:`` may hold anchors too (``base: &servo_base {...}``) for ``<<: *servo_base``.
"""

from __future__ import annotations

import re
from typing import Any

from umbra.connectors.errors import Diagnostic, Location
from umbra.connectors.frames import NAME_RE
from umbra.runtime.graph.located_yaml import MAX_NODES, YList, YMap
from umbra.runtime.graph.parse_base import _kind
from umbra.runtime.hints import did_you_mean

REFERENCE = re.compile(r"^\$(\$?)([A-Za-z_][A-Za-z0-9_]*)$")


def substitute(doc: Any, problems: list[Diagnostic]) -> Any:
    """``doc`` with its ``values:`` taken out and every ``$NAME`` replaced; a problem (an unknown
    name, a bad ``values:``) is appended to ``problems`` at its location."""
    if not isinstance(doc, YMap) or "values" not in doc:
        values: YMap | None = None
    else:
        values = doc.pop("values")
        where = doc.val_loc.pop("values")
        doc.key_loc.pop("values")
        if not isinstance(values, YMap):
            problems.append(
                Diagnostic(
                    where, f"`values` must be a mapping of NAME: VALUE, found {_kind(values)}"
                )
            )
            values = None
        else:
            _check_values(values, problems)
    if isinstance(doc, YMap | YList):
        _walk(doc, values, problems, _Budget())
    return doc


class _Budget:
    """The nodes references have expanded to so far, against ``MAX_NODES``."""

    def __init__(self) -> None:
        self.used = 0
        self.sizes: dict[int, int] = {}

    def take(self, value: Any) -> bool:
        """Count ``value``'s nodes; False once the total passes ``MAX_NODES``."""
        self.used += self.size(value)
        return self.used <= MAX_NODES

    def size(self, value: Any) -> int:
        if id(value) not in self.sizes:
            kids = value.values() if isinstance(value, dict) else value
            nested = isinstance(value, dict | list)
            self.sizes[id(value)] = 1 + (sum(self.size(k) for k in kids) if nested else 0)
        return self.sizes[id(value)]


def _check_values(values: YMap, problems: list[Diagnostic]) -> None:
    for name in values:
        if not isinstance(name, str) or not NAME_RE.match(name):
            problems.append(
                Diagnostic(
                    values.key_loc[name], f"a value's name must be an identifier, found {name!r}"
                )
            )
    inner: list[Diagnostic] = []
    _walk(values, None, inner, _Budget())
    for problem in inner:
        problems.append(
            Diagnostic(problem.location, "a value of `values:` cannot name another value")
        )


def _walk(
    node: YMap | YList, values: YMap | None, problems: list[Diagnostic], budget: _Budget
) -> None:
    """Replace references in ``node``'s children, in place, then walk into its collections."""
    slots: list[tuple[Any, dict[Any, Location] | list[Location]]]
    if isinstance(node, YMap):
        slots = [(key, node.val_loc) for key in node]
    else:
        slots = [(i, node.item_loc) for i in range(len(node))]
    for slot, locs in slots:
        replaced = _replace(node[slot], locs[slot], values, problems)
        if replaced is not None:
            if not budget.take(replaced[0]):
                problems.append(
                    Diagnostic(
                        locs[slot], f"`values:` references expand to more than {MAX_NODES} nodes"
                    )
                )
                return
            node[slot], locs[slot] = replaced
        if isinstance(node[slot], YMap | YList) and not _is_value(node[slot], values):
            _walk(node[slot], values, problems, budget)


def _is_value(node: Any, values: YMap | None) -> bool:
    """Whether ``node`` is one of the values themselves (already walked, shared by reference)."""
    return values is not None and any(node is v for v in values.values())


def _replace(
    value: Any, loc: Location, values: YMap | None, problems: list[Diagnostic]
) -> tuple[Any, Location] | None:
    """``(value, its location)`` that a ``$NAME`` text stands for; None when ``value`` is no
    reference (or names no value: then a problem says so)."""
    match = REFERENCE.match(value) if isinstance(value, str) else None
    if match is None:
        return None
    escaped, name = match.groups()
    if escaped:
        return value[1:], loc
    if values is None or name not in values:
        known = [str(k) for k in values] if values is not None else []
        where = "" if values is not None else " (the graph has no `values:`)"
        problems.append(
            Diagnostic(
                loc,
                f"`${name}` names no value of `values:`{where}{did_you_mean(name, known)}",
                "write `$$" + name + "` for the text itself",
            )
        )
        return None
    return values[name], values.val_loc[name]
