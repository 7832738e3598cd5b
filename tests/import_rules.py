"""The direction of imports in the project, declared once, and a checker that reads every file's
imports with ``ast`` (nothing is imported or run).

``docs/code-map.md`` explains these rules to a newcomer; ``tests/test_import_direction.py``
holds the code to them and the map's table of domain arrows to ``DOMAIN_ARROWS``.

Every import counts: at module level, inside functions (lazy imports) and under
``if TYPE_CHECKING:`` (a type-only import is still an arrow a reader must follow).
"""

from __future__ import annotations

import ast
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

#: The package the layers are installed under (``runtime/`` is ``umbra.runtime``, setup.py).
PACKAGE = "umbra"

#: The project's layers (folders, installed as ``umbra.<layer>``) and what each may import of them.
LAYERS: dict[str, set[str]] = {
    "connectors": {"connectors"},  # the base layer: message types, ports, module base class
    "modules": {"connectors", "modules"},  # domains: modules and their plain math
    "runtime": {"connectors", "runtime"},  # runs graphs; finds modules by entry point only
}

#: Domain packages under ``modules/`` and the other domains each may import. Vocabulary that
#: several domains speak (message types, their shared helpers) lives in ``connectors``, which every
#: domain may import.
DOMAIN_ARROWS: dict[str, set[str]] = {
    "geometry": set(),
    "generic": set(),
    "webdoor": set(),
    "arm": {"geometry"},
    "calib": {"geometry"},
    "ptu": {"calib", "geometry"},
    "servo": {"calib", "geometry"},
    "trajectory": {"arm", "geometry"},
    "vision": {"arm", "calib", "geometry"},
    "world": {"arm", "geometry"},
    "view3d": {"arm", "calib", "geometry", "webdoor"},
    "operator": {"arm", "geometry", "servo", "vision", "webdoor"},
    "sketch": {"arm", "calib", "geometry", "ptu", "trajectory", "vision", "world"},
    "sketch_page": {"geometry", "operator", "sketch", "trajectory", "webdoor"},
}

#: Declared exceptions, file -> (imported package prefix, why). Each is a debt named here so
#: that no new one comes in unseen.
EXCEPTIONS: dict[str, tuple[str, str]] = {
    "modules/generic/recording.py": (
        "umbra.runtime.recording",
        "the Recorder module writes and reads the runtime's recording format",
    ),
    "modules/generic/recorder.py": (
        "umbra.runtime.recording",
        "the Recorder module takes the runtime's image choices and run-folder rule",
    ),
    "modules/world/trial_runner.py": (
        "umbra.runtime",
        "`umbra trials` runs whole graphs: an application on top of the runtime",
    ),
}

#: Import cycles between files that are known and declared (each a set of module names).
KNOWN_CYCLES: list[set[str]] = [
    {  # helpers split from the client take it as their owner; typed under TYPE_CHECKING
        "umbra.modules.calib.visca.client",
        "umbra.modules.calib.visca.client_moves",
        "umbra.modules.calib.visca.client_startup",
        "umbra.modules.calib.visca.client_wire",
    },
    # a module's parts take it as their owner, typed under TYPE_CHECKING (the module builds
    # them at start and calls them; the parts read its ports and parameters)
    {
        "umbra.modules.operator.console",
        "umbra.modules.operator.console_events",
        "umbra.modules.operator.console_view",
    },
    {"umbra.modules.sketch_page.page_control", "umbra.modules.sketch_page.sketch_page"},
    {"umbra.modules.view3d.view3d", "umbra.modules.view3d.view3d_push"},
    {"umbra.modules.vision.digicam", "umbra.modules.vision.digicam_sim"},
]


@dataclass(frozen=True)
class Rules:
    """What may import what (see the module constants for the project's own)."""

    layers: Mapping[str, set[str]] = field(default_factory=lambda: LAYERS)
    domains: Mapping[str, set[str]] = field(default_factory=lambda: DOMAIN_ARROWS)
    exceptions: Mapping[str, tuple[str, str]] = field(default_factory=lambda: EXCEPTIONS)
    known_cycles: list[set[str]] = field(default_factory=lambda: KNOWN_CYCLES)


def module_files(root: Path, layers: Iterable[str]) -> dict[str, Path]:
    """Module name (``umbra.<layer>...``) -> file for every ``.py`` file of the ``layers``
    folders under ``root``."""
    found = {}
    for top in layers:
        for path in sorted((root / top).rglob("*.py")):
            parts = path.relative_to(root).with_suffix("").parts
            if parts[-1] == "__init__":
                parts = parts[:-1]
            found[".".join((PACKAGE, *parts))] = path
    return found


def _layer(module: str) -> str:
    """``umbra.runtime.scheduler`` -> ``runtime``."""
    return module.split(".")[1]


def imports_of(path: Path, module: str) -> list[tuple[int, str]]:
    """``(line, imported name)`` of every import in ``path`` (module ``module``), relative ones
    made absolute; ``from a import b`` gives ``a.b`` (a submodule or a name in ``a``)."""
    tree = ast.parse(path.read_text(), filename=str(path))
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*anchor, base] if base else anchor)
            out += [(node.lineno, f"{base}.{alias.name}") for alias in node.names]
    return out


def _domain(module: str) -> str:
    parts = module.split(".")
    return parts[2] if parts[1] == "modules" and len(parts) > 3 else ""


def _resolve(name: str, files: Mapping[str, Path]) -> str:
    """The project module ``name`` refers to (its longest known prefix); "" when none."""
    while name and name not in files:
        name = name.rpartition(".")[0]
    return name


def judge(module: str, target: str, rules: Rules) -> str:
    """Why ``module`` may not import ``target`` (both project modules); "" when it may."""
    top, target_top = _layer(module), _layer(target)
    if target_top not in rules.layers.get(top, {target_top}):
        return f"`{top}` may import only {', '.join(sorted(rules.layers[top]))}"
    src, dst = _domain(module), _domain(target)
    if not src or not dst or src == dst:
        return ""
    if src not in rules.domains:
        return f"domain `{src}` is not declared in DOMAIN_ARROWS"
    if dst in rules.domains[src]:
        return ""
    allowed = ", ".join(sorted(rules.domains[src])) or "no other domain"
    return f"domain `{src}` may import {allowed}"


def violations(root: Path, rules: Rules | None = None) -> list[str]:
    """``FILE:LINE: imports NAME: why`` for every import against ``rules`` under ``root``."""
    rules = rules or Rules()
    files = module_files(root, rules.layers)
    found = []
    for module, path in files.items():
        rel = path.relative_to(root).as_posix()
        excused = rules.exceptions.get(rel)
        for line, name in imports_of(path, module):
            target = _resolve(name, files)
            if not target or (excused and target.startswith(excused[0])):
                continue
            why = judge(module, target, rules)
            if why:
                found.append(f"{rel}:{line}: imports {target}: {why}")
    return old_name_imports(root, rules.layers, rules) + found


def old_name_imports(root: Path, folders: Iterable[str], rules: Rules | None = None) -> list[str]:
    """``FILE:LINE: imports NAME: ...`` for every import of a layer by its old top-level name
    (``runtime``, not ``umbra.runtime``) in the ``.py`` files under ``folders``: the installed
    package has no such names, and from a checkout they would load a second copy of the folder's
    modules."""
    rules = rules or Rules()
    found = []
    for folder in folders:
        for path in sorted((root / folder).rglob("*.py")):
            parts = path.relative_to(root).with_suffix("").parts
            parts = parts[:-1] if parts[-1] == "__init__" else parts
            for line, name in imports_of(path, ".".join((PACKAGE, *parts))):
                if name.split(".")[0] in rules.layers:
                    rel = path.relative_to(root).as_posix()
                    found.append(f"{rel}:{line}: imports {name}: import {PACKAGE}.{name}")
    return found


def import_graph(root: Path, rules: Rules | None = None) -> dict[str, set[str]]:
    """Module -> the project modules it imports (every import, see the module docstring)."""
    rules = rules or Rules()
    files = module_files(root, rules.layers)
    graph: dict[str, set[str]] = {m: set() for m in files}
    for module, path in files.items():
        for _line, name in imports_of(path, module):
            target = _resolve(name, files)
            if target and target != module:
                graph[module].add(target)
    return graph


def cycles(graph: Mapping[str, Iterable[str]]) -> list[set[str]]:
    """The strongly connected sets of more than one node (Tarjan's algorithm, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    found: list[set[str]] = []
    for start in graph:
        if start in index:
            continue
        work = [(start, iter(graph.get(start, ())))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, edges = work[-1]
            for nxt in edges:
                if nxt not in index:
                    index[nxt] = low[nxt] = len(index)
                    stack.append(nxt)
                    on_stack.add(nxt)
                    work.append((nxt, iter(graph.get(nxt, ()))))
                    break
                if nxt in on_stack:
                    low[node] = min(low[node], index[nxt])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    group = set()
                    while True:
                        member = stack.pop()
                        on_stack.discard(member)
                        group.add(member)
                        if member == node:
                            break
                    if len(group) > 1:
                        found.append(group)
    return found


def new_cycles(root: Path, rules: Rules | None = None) -> list[set[str]]:
    """Import cycles between files under ``root`` that ``rules`` does not declare."""
    rules = rules or Rules()
    return [c for c in cycles(import_graph(root, rules)) if c not in rules.known_cycles]
