"""A graph that extends another: ``extends: base.yaml`` composes two located documents into one.

::

    extends: tool_pickup.yaml       # relative to this file; its base may extend another
    graph: tool_pickup_3d           # a scalar given here replaces the base's
    processes: {umbra: !replace {}} # `!replace`: this mapping (or list) instead of the base's
    modules:
      servo: {params: {max_linear: 0.03}}   # merged key by key into the base's `servo`
      view3d: {type: View3D, process: umbra, rate: 30}   # a module the base has not
    connections:                    # added after the base's
      - camera.image -> view3d.wrist_image
    remove_connections:             # taken out of the base's
      - servo.status -> plot.status

Mappings merge key by key at every depth (sections, a module, its ``params``, a parameter whose
value is a mapping); a key given here wins; a scalar or a list given here replaces the base's.
``connections`` is the one list that adds. Every part keeps the location where it is written, in
whichever file, so ``umbra check`` reports a problem of the base at the base's line. A chain of
files is at most ``MAX_CHAIN`` long; a cycle, a missing or unreadable base are errors at the
``extends`` line.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from umbra.connectors.errors import CheckFailed, Diagnostic, Location, UserError
from umbra.connectors.user_files import read_bytes
from umbra.runtime.graph.located_yaml import MAX_BYTES, YList, YMap, load_located
from umbra.runtime.graph.parse_base import _kind
from umbra.runtime.graph.parse_modules import CONNECTION_RE
from umbra.runtime.hints import did_you_mean

MAX_CHAIN = 8
#: Keys this composition consumes: the parser never sees them.
COMPOSE_KEYS = ("extends", "remove_connections")


@dataclass
class Composed:
    """The composed document, the text of every file read (the given one first) and the problems
    found that still let the rest be read."""

    doc: Any
    texts: dict[str, str] = field(default_factory=dict)
    problems: list[Diagnostic] = field(default_factory=list)

    @property
    def extends(self) -> bool:
        """Whether the document is composed from more than one file."""
        return len(self.texts) > 1


def compose(doc: Any, file: str, text: str) -> Composed:
    """``doc`` (read from ``file``) with the graphs it extends merged in; CheckFailed when a base
    cannot be read (nothing sound could be checked without it)."""
    out = Composed(doc, {file: text})
    out.doc = _resolve(doc, file, [_real(file)], out)
    return out


def _real(file: str) -> Path:
    return Path(file).resolve()


def _fatal(loc: Location, message: str) -> CheckFailed:
    return CheckFailed([Diagnostic(loc, message)])


def _resolve(doc: Any, file: str, chain: list[Path], out: Composed) -> Any:
    if not isinstance(doc, YMap):
        return doc
    if "extends" not in doc:
        if "remove_connections" in doc:
            out.problems.append(
                Diagnostic(
                    doc.key_loc["remove_connections"],
                    "`remove_connections` takes connections out of the graph this one extends; "
                    "this graph has no `extends:`",
                )
            )
            del doc["remove_connections"]
        return doc
    value, loc = doc["extends"], doc.val_loc["extends"]
    if not isinstance(value, str) or not value.strip():
        raise _fatal(
            loc,
            "`extends` names the graph file this one extends (a path relative to this file), "
            f"found {_kind(value)}",
        )
    path = Path(file).parent / value
    shown = os.path.normpath(path)
    real = path.resolve()
    if real in chain:
        cycle = " -> ".join([*(p.name for p in chain[chain.index(real) :]), real.name])
        raise _fatal(loc, f"`extends: {value}` makes a cycle: {cycle}")
    if len(chain) >= MAX_CHAIN:
        raise _fatal(loc, f"`extends`: a chain of more than {MAX_CHAIN} graph files")
    if path.is_dir():
        raise _fatal(loc, f"`extends`: `{shown}` is a directory, expected a graph file (.yaml)")
    if not path.exists():
        raise _fatal(
            loc, f"`extends`: no such graph file `{shown}` (the path is relative to {file})"
        )
    try:
        data = read_bytes(path, "graph file", MAX_BYTES)
    except UserError as exc:
        raise _fatal(loc, f"`extends`: {str(exc).replace(': error: ', ': ', 1)}") from None
    base_doc = load_located(data, shown)  # a problem in it is reported at its own line
    out.texts[shown] = data.decode("utf-8", "replace")
    if not isinstance(base_doc, YMap):
        raise _fatal(loc, f"`extends`: `{shown}` is {_kind(base_doc)}, expected a graph mapping")
    base = _resolve(base_doc, shown, [*chain, real], out)
    return _merge_graph(base, doc, out)


def _merge_graph(base: YMap, over: YMap, out: Composed) -> YMap:
    """``over`` on ``base``: sections merged, connections added and removed."""
    merged = merge(base, over, skip=("extends", "remove_connections", "connections"))
    conns = base.get("connections")
    if "remove_connections" in over:
        conns = _remove(conns, over, out)
    added = over.get("connections")
    if "connections" in over and (getattr(added, "replace", False) or not isinstance(conns, YList)):
        _put(merged, "connections", added, over.key_loc["connections"], over.val_loc["connections"])
    elif isinstance(conns, YList):
        together = YList(conns)
        together.loc, together.item_loc = conns.loc, list(conns.item_loc)
        if isinstance(added, YList):
            together.extend(added)
            together.item_loc.extend(added.item_loc)
        elif "connections" in over and added is not None:  # the parser says what is wrong
            together = added
        # neither writes `connections` when the base has none and `remove_connections` made them
        key_loc = over.key_loc.get("connections", base.key_loc.get("connections", conns.loc))
        val_loc = over.val_loc.get("connections", base.val_loc.get("connections", conns.loc))
        _put(merged, "connections", together, key_loc, val_loc)
    return merged


def merge(base: YMap, over: YMap, skip: tuple[str, ...] = ()) -> YMap:
    """``over`` merged into ``base`` key by key, recursively for mappings (but those tagged
    ``!replace``); keys of ``skip`` are left out. Locations follow the value taken."""
    out = YMap()
    out.loc, out.key_loc, out.val_loc = over.loc, {}, {}
    for key, value in base.items():
        if key not in skip:
            _put(out, key, value, base.key_loc[key], base.val_loc[key])
    for key, value in over.items():
        if key in skip:
            continue
        old = out.get(key)
        if isinstance(old, YMap) and isinstance(value, YMap) and not value.replace:
            value = merge(old, value)
        _put(out, key, value, over.key_loc[key], over.val_loc[key])
    return out


def _put(into: YMap, key: Any, value: Any, key_loc: Location, val_loc: Location) -> None:
    into[key] = value
    into.key_loc[key] = key_loc
    into.val_loc[key] = val_loc


def _remove(conns: Any, over: YMap, out: Composed) -> Any:
    """The base's connections without those of ``over``'s ``remove_connections``."""
    gone = over["remove_connections"]
    where = over.val_loc["remove_connections"]
    if not isinstance(gone, YList):
        out.problems.append(
            Diagnostic(where, f"`remove_connections` must be a list, found {_kind(gone)}")
        )
        return conns
    present = list(conns) if isinstance(conns, YList) else []
    keys = [connection_key(c) for c in present]
    drop: set[int] = set()
    for item, loc in zip(gone, gone.item_loc, strict=True):
        key = connection_key(item)
        if key is None:
            out.problems.append(
                Diagnostic(
                    loc,
                    "a connection to remove is written as in `connections` "
                    f"(`module.output -> module.input`), found {_kind(item)}",
                )
            )
        elif key not in keys:
            shown = [" ".join(k) for k in keys if k is not None]
            out.problems.append(
                Diagnostic(
                    loc,
                    f"`remove_connections`: the graph this one extends has no connection "
                    f"`{' '.join(key)}`{did_you_mean(' '.join(key), shown)}",
                )
            )
        else:
            drop.update(i for i, k in enumerate(keys) if k == key)
    kept = YList(c for i, c in enumerate(present) if i not in drop)
    kept.loc = conns.loc if isinstance(conns, YList) else where
    kept.item_loc = [loc for i, loc in enumerate(getattr(conns, "item_loc", [])) if i not in drop]
    return kept


def connection_key(item: Any) -> tuple[str, str, str] | None:
    """``("a.out", "->", "b.in")`` of a connection as written (text or from/to/delayed)."""
    if isinstance(item, str):
        match = CONNECTION_RE.match(item)
        if match is None:
            return None
        return f"{match['sm']}.{match['sp']}", match["arrow"], f"{match['dm']}.{match['dp']}"
    if (
        isinstance(item, dict)
        and isinstance(item.get("from"), str)
        and isinstance(item.get("to"), str)
    ):
        return item["from"], "~>" if item.get("delayed") is True else "->", item["to"]
    return None
