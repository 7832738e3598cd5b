"""Module types by name, from the ``umbra.modules`` entry-point group.

A third-party package adds module types by declaring, in its own pyproject.toml::

    [project.entry-points."umbra.modules"]
    MyFilter = "my_package.filter:MyFilter"

The runtime never imports a concrete module by name; it asks the registry.

A type name belongs to one distribution. Two installed distributions that register different
objects under one name (a plug-in's ``Gain`` beside the built-in one) make discovery fail with a
:class:`UserError` naming both distributions and how to rename one: the registry never picks one
silently.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from importlib.metadata import EntryPoint, entry_points
from typing import Any

from umbra.connectors.errors import UserError
from umbra.connectors.module import Module
from umbra.runtime.hints import did_you_mean

GROUP = "umbra.modules"


@dataclass
class Registry:
    """Module classes by type name, loaded lazily from entry points (plus any added directly)."""

    _types: dict[str, type[Module[Any]]] = field(default_factory=dict)
    _entry_points: dict[str, EntryPoint] | None = None
    broken: dict[str, str] = field(default_factory=dict)

    def _eps(self) -> dict[str, EntryPoint]:
        if self._entry_points is None:
            found: dict[str, list[EntryPoint]] = {}
            for ep in entry_points(group=GROUP):
                same = found.setdefault(ep.name, [])
                if all(other.value != ep.value for other in same):  # one dist seen twice: once
                    same.append(ep)
            clashes = {name: eps for name, eps in found.items() if len(eps) > 1}
            if clashes:
                raise UserError(_clash_message(clashes))
            self._entry_points = {name: eps[0] for name, eps in found.items()}
        return self._entry_points

    def add(self, cls: type[Module[Any]], name: str | None = None) -> None:
        """Register ``cls`` under ``name`` (default: its type name) — for tests and plug-ins."""
        self._types[name or cls.type_name()] = cls

    def names(self) -> list[str]:
        """All known type names, sorted."""
        return sorted(set(self._types) | set(self._eps()))

    def get(self, name: str) -> type[Module[Any]] | None:
        """The class for ``name``, or None when unknown. Import failures are kept in ``broken``."""
        if name in self._types:
            return self._types[name]
        ep = self._eps().get(name)
        if ep is None:
            return None
        try:
            cls = ep.load()
        except Exception as exc:  # a broken plug-in must not take the CLI down
            self.broken[name] = f"{type(exc).__name__}: {exc}"
            return None
        if not (isinstance(cls, type) and issubclass(cls, Module)):
            self.broken[name] = f"entry point does not name a Module subclass: {cls!r}"
            return None
        self._types[name] = cls
        return cls

    def require(self, name: str) -> type[Module[Any]]:
        """The class for ``name``; ``UserError`` when unknown or broken."""
        cls = self.get(name)
        if cls is None:
            raise UserError(self.missing(name))
        return cls

    def missing(self, name: str) -> str:
        """Why ``get(name)`` gave None: the load failure, or "unknown" with a spelling hint."""
        if name in self.broken:
            return f"module type `{name}` failed to load: {self.broken[name]}"
        return f"unknown module type `{name}`{did_you_mean(name, self.names())}"


def _distribution(ep: EntryPoint) -> str:
    dist = getattr(ep, "dist", None)
    return f"{dist.name} {dist.version}" if dist is not None else "an unknown distribution"


def _clash_message(clashes: dict[str, list[EntryPoint]]) -> str:
    """What went wrong and how to fix it, for each type name registered more than once."""
    lines = []
    for name, eps in sorted(clashes.items()):
        owners = " and ".join(f"{_distribution(ep)} ({ep.value})" for ep in eps)
        lines.append(f"module type `{name}` is registered by {owners}")
    example = next(iter(sorted(clashes)))
    return (
        f"expected each name in the `{GROUP}` entry-point group to name one module type, found "
        + "; ".join(lines)
        + ". Rename the plug-in's type: in its pyproject.toml under "
        f'[project.entry-points."{GROUP}"] give it a name of its own (e.g. '
        f'`My{example} = "..."`, and TYPE = "My{example}" on the class), reinstall it, and use '
        "that name in graphs; or uninstall one of the distributions (pip uninstall NAME)"
    )
