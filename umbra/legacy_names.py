"""The import names of umbra-smart before 0.2, ``connectors``, ``modules`` and ``runtime``, kept
for a deprecation period as aliases of ``umbra.connectors``, ``umbra.modules`` and
``umbra.runtime``: ``import runtime.scheduler`` gives the very module object
``umbra.runtime.scheduler`` (one copy of every class) and a DeprecationWarning that names the new
import.

An alias never shadows a user's own package of the same name. The finder of the old top-level
names sits at the END of ``sys.meta_path``: it answers only when every other finder (the path,
a zip, an editable install) found nothing, so a ``runtime/`` package on ``sys.path`` is imported
as it would be without us. A second finder, at the front, answers only for the submodules of an
old name whose top-level module *is* ours (``sys.modules["runtime"] is umbra.runtime``); without
it the path finder would load ``runtime/scheduler.py`` a second time under the old name.

Installed by ``import umbra``, and at interpreter start-up by the distribution's
``umbra-smart-legacy-names.pth`` (so that an old script that never imports ``umbra`` still runs).
"""

from __future__ import annotations

import sys

# The .pth imports this module in every interpreter of the environment: at module level it
# imports only sys (already loaded); the import machinery and warnings load when an old name is
# actually imported.
TYPE_CHECKING = False
if TYPE_CHECKING:
    from importlib.machinery import ModuleSpec
    from types import CodeType, ModuleType

#: Old top-level name -> the package it now is.
LEGACY_NAMES: dict[str, str] = {
    "connectors": "umbra.connectors",
    "modules": "umbra.modules",
    "runtime": "umbra.runtime",
}


class _AliasLoader:
    """Loads an old name as the module of its new name (the same object, not a copy)."""

    def __init__(self, new_name: str) -> None:
        self.new_name = new_name

    def create_module(self, spec: ModuleSpec) -> None:
        return None  # a placeholder, replaced in sys.modules by exec_module

    def exec_module(self, module: ModuleType) -> None:
        import importlib

        _warn(module.__name__, self.new_name)
        sys.modules[module.__name__] = importlib.import_module(self.new_name)

    def get_code(self, fullname: str) -> CodeType | None:
        """The new module's code, for ``python -m <old name>`` (runpy asks the loader)."""
        import importlib.util

        _warn(fullname, self.new_name)
        spec = importlib.util.find_spec(self.new_name)
        return spec.loader.get_code(self.new_name) if spec and spec.loader else None  # type: ignore[attr-defined]


class LegacyNameFinder:
    """``children=False``: the old top-level names (put at the end of ``sys.meta_path``);
    ``children=True``: submodules of an old name that is already our alias (put at the front)."""

    def __init__(self, children: bool) -> None:
        self.children = children

    def find_spec(
        self, fullname: str, path: object = None, target: object = None
    ) -> ModuleSpec | None:
        top, dot, rest = fullname.partition(".")
        new_top = LEGACY_NAMES.get(top)
        if new_top is None or bool(dot) != self.children:
            return None
        import importlib.util
        from importlib.machinery import ModuleSpec

        if not self.children:
            return ModuleSpec(fullname, _AliasLoader(new_top))
        ours = sys.modules.get(new_top)
        if ours is None or sys.modules.get(top) is not ours:
            return None  # the old name is someone else's package (or not imported): not ours
        new_name = f"{new_top}.{rest}"
        if importlib.util.find_spec(new_name) is None:
            return None
        return ModuleSpec(fullname, _AliasLoader(new_name))


def install_legacy_names(meta_path: list | None = None) -> None:
    """Put the two finders on ``meta_path`` (``sys.meta_path``), once."""
    meta_path = sys.meta_path if meta_path is None else meta_path
    if any(isinstance(f, LegacyNameFinder) for f in meta_path):
        return
    meta_path.insert(0, LegacyNameFinder(children=True))
    meta_path.append(LegacyNameFinder(children=False))


def _warn(old: str, new: str) -> None:
    import warnings

    warnings.warn(
        f"`{old}` is a deprecated name of umbra-smart's `{new}`: import `{new}` instead "
        "(the old top-level names go in a later release)",
        DeprecationWarning,
        stacklevel=_importer_level(),
    )


def _importer_level() -> int:
    """The ``stacklevel`` of the first frame outside this file and the import machinery (the
    user's import statement), so that the warning points there (and shows in ``__main__``)."""
    level, frame = 2, sys._getframe(2)  # 2: exec_module or get_code, the caller of _warn
    while frame is not None:
        name = frame.f_code.co_filename
        if "importlib" in name and "_bootstrap" in name:
            frame = frame.f_back  # warnings.warn skips these frames itself: not counted
        elif name == __file__ or "importlib" in name:
            level, frame = level + 1, frame.f_back
        else:
            break
    return level
