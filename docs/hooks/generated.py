"""MkDocs hook (``mkdocs.yml``: ``hooks:``): the pages generated from the code and the results,
added to the site at build time, never written by hand: the module reference (``umbra
describe``), the command-line reference (``--help``) and the benchmark tables
(``benchmarks/results/*.json``).

``python docs/hooks/generated.py DIR`` writes the same pages under ``DIR`` to read them without
building the site."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType
from typing import Any

HERE = Path(__file__).resolve().parent
GENERATORS = ("gen_modules", "gen_cli", "gen_benchmarks")


def _load(name: str) -> ModuleType:
    spec = importlib.util.spec_from_file_location(f"umbra_docs_{name}", HERE / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def pages() -> dict[str, str]:
    """Each generated page's path under ``docs/`` and its Markdown."""
    found = {}
    for name in GENERATORS:
        module = _load(name)
        found[module.PAGE] = module.render()
    return found


def on_files(files: Any, config: Any) -> Any:
    """Add the generated pages to the site's files (mkdocs >= 1.6)."""
    from mkdocs.structure.files import File

    for path, text in pages().items():
        files.append(File.generated(config, path, content=text))
    return files


if __name__ == "__main__":
    out = Path(sys.argv[1] if len(sys.argv) > 1 else "site-pages")
    for path, text in pages().items():
        (out / path).parent.mkdir(parents=True, exist_ok=True)
        (out / path).write_text(text)
        print(out / path)
