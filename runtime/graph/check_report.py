"""How the graph's checks report a problem: at the YAML node at fault, with an optional hint;
every check reports and goes on, so that ``umbra check`` lists every problem at once."""

from __future__ import annotations

from typing import Protocol

from umbra.connectors.errors import Location


class Report(Protocol):
    """``report(loc, message, hint="")``: one problem at ``loc`` (a ``Diagnostic``)."""

    def __call__(self, loc: Location, message: str, hint: str = "") -> None: ...
