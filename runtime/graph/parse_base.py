"""What every part of the graph-file parser shares: the problems found so far, each with its
location, and the checks of a mapping, its keys, a positive number and a rate."""

from __future__ import annotations

import math
from typing import Any

from umbra.connectors.errors import Diagnostic, Location
from umbra.connectors.limits import MAX_RATE_HZ, MIN_RATE_HZ
from umbra.connectors.safe_yaml import boolean_hint
from umbra.runtime.graph.located_yaml import YMap
from umbra.runtime.hints import did_you_mean


def _kind(value: Any) -> str:
    if value is None:
        return "nothing"
    if isinstance(value, dict):
        return "a mapping"
    if isinstance(value, list):
        return "a list"
    return f"{type(value).__name__} {value!r}"[:80] + boolean_hint(value)


def _plain(value: Any) -> Any:
    """YMap/YList -> dict/list recursively (parameters are validated as plain values)."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_plain(v) for v in value]
    return value


class ParserBase:
    """The parser's state: the file, its text, and the problems found (``diagnostics``)."""

    def __init__(self, file: str, text: str, others: dict[str, str] | None = None) -> None:
        self.file = file
        #: the lines of each file read, by file name (a graph that extends another reads two)
        self.lines = {name: t.split("\n") for name, t in {**(others or {}), file: text}.items()}
        self.problems: list[Diagnostic] = []
        self.broken: set[str] = set()

    def error(self, loc: Location | None, message: str, hint: str = "") -> None:
        self.problems.append(Diagnostic(loc or Location(self.file, 1, 1), message, hint))

    # -- helpers ----------------------------------------------------------------------------
    def expect_map(self, value: Any, loc: Location, what: str) -> YMap | None:
        if isinstance(value, YMap):
            return value
        self.error(loc, f"{what} must be a mapping, found {_kind(value)}")
        return None

    def unknown_keys(self, mapping: YMap, allowed: tuple[str, ...], what: str) -> None:
        for key in mapping:
            if key not in allowed:
                self.error(
                    mapping.key_loc[key],
                    f"unknown key `{key}` in {what}{did_you_mean(str(key), allowed)}",
                )

    def col_of(self, loc: Location, offset: int) -> Location:
        """Location ``offset`` characters into a plain or quoted scalar that starts at ``loc``."""
        lines = self.lines.get(loc.file, [])
        line = lines[loc.line - 1] if 0 < loc.line <= len(lines) else ""
        quoted = 1 if line[loc.column - 1 : loc.column] in ("'", '"') else 0
        return Location(loc.file, loc.line, loc.column + quoted + offset)

    # -- sections -----------------------------------------------------------------------------
    def positive(self, value: Any, loc: Location, what: str) -> float | None:
        if (
            isinstance(value, bool)
            or not isinstance(value, int | float)
            or not value > 0
            or not math.isfinite(value)
        ):
            self.error(loc, f"{what} must be a positive number, found {value!r}")
            return None
        return float(value)

    def rate(self, value: Any, loc: Location, module: str) -> float | None:
        """A module's rate [Hz], within [MIN_RATE_HZ, MAX_RATE_HZ]."""
        rate = self.positive(value, loc, f"rate [Hz] of module `{module}`")
        if rate is not None and not MIN_RATE_HZ <= rate <= MAX_RATE_HZ:
            self.error(
                loc,
                f"rate of module `{module}` must be from {MIN_RATE_HZ:g} to {MAX_RATE_HZ:g} Hz, "
                f"found {value!r}",
            )
            return None
        return rate
