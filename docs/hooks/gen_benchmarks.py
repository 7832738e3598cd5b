"""The benchmark figures, generated from ``benchmarks/results/*.json`` (run by the site's build
hook, ``generated.py``): one table per results file, its goals first.

Every results file is written by ``benchmarks.common.write_results``: ``benchmark``, ``quick``,
``when`` and ``machine``, then the benchmark's own figures. A goal is a key named ``goals`` (a
mapping of goal -> met, or goal -> ``{"met": ...}``), ``goal_met`` or ``meets_goal``; a
``goals`` mapping of numbers holds the thresholds. ``*.quick.json`` files (short smoke runs, not
kept in the repository) are left out.
"""

from __future__ import annotations

import ast
import json
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "benchmarks" / "results"
PAGE = "reference/benchmarks.md"
#: figures shown per table; the rest are in the JSON file the table names
MAX_ROWS = 60
#: a list longer than this is summarized (count, median, range), not written out
MAX_LIST = 6
_HEAD = ("benchmark", "quick", "when", "machine")
_GOAL_FLAGS = ("goal_met", "meets_goal", "met")

Path_ = tuple[str, ...]


def result_files() -> list[Path]:
    """The reference results, by name (quick runs left out)."""
    return sorted(p for p in RESULTS.glob("*.json") if not p.name.endswith(".quick.json"))


def render() -> str:
    out = [
        "# Benchmark results",
        "",
        "Generated from `benchmarks/results/*.json` when the site is built: one table per "
        "results file, its goals first (**met** or **missed**), then every figure it holds "
        "(lists summarized as count, median and range). What each benchmark measures and how "
        "to run it: [Benchmarks](../guide/benchmarks.md).",
    ]
    for path in result_files():
        out += ["", *section(path)]
    return "\n".join(out) + "\n"


def section(path: Path) -> list[str]:
    """The heading, the benchmark's description, its run and one table of its results."""
    data = json.loads(path.read_text())
    name = str(data.get("benchmark", path.stem))
    script = ROOT / "benchmarks" / f"bench_{name}.py"
    if not script.exists():  # a variant of another benchmark's results (links_umbra_noauth_open)
        script = ROOT / "benchmarks" / f"bench_{name.split('_')[0]}.py"
    machine = data.get("machine", {})
    lines = [f"## {path.stem}", ""]
    if script.exists():
        lines += [_describe(script), ""]
    lines += [
        f"Measured {data.get('when', '?')} (Python {machine.get('python', '?')}, "
        f"{machine.get('cpu', '?')}); file `benchmarks/results/{path.name}`"
        + (f"; run `python benchmarks/{script.name}`." if script.exists() else "."),
        "",
        "| figure | value |",
        "| --- | --- |",
    ]
    goals = [(p, v) for p, v in leaves(data) if is_goal(p) and isinstance(v, bool)]
    figures = [(p, v) for p, v in leaves(data) if p[0] not in _HEAD and (p, v) not in goals]
    for p, v in goals:
        lines.append(f"| goal: {_path(p)} | {'**met**' if v else '**missed**'} |")
    for p, v in figures[:MAX_ROWS]:
        lines.append(f"| {_path(p)} | {_value(v)} |")
    if len(figures) > MAX_ROWS:
        lines.append(f"| … | {len(figures) - MAX_ROWS} more figures in the file |")
    return lines


def leaves(data: Any, path: Path_ = ()) -> Iterator[tuple[Path_, Any]]:
    """Every figure of a results file as (key path, value); a list of numbers is one value."""
    if isinstance(data, dict):
        for key, value in data.items():
            yield from leaves(value, (*path, str(key)))
    elif isinstance(data, list) and data and all(isinstance(v, dict) for v in data):
        if len(data) > MAX_LIST:
            yield path, f"{len(data)} entries"
        else:
            for i, value in enumerate(data):
                yield from leaves(value, (*path, f"[{i}]"))
    else:
        yield path, data


def is_goal(path: Path_) -> bool:
    """A verdict on a goal: under a ``goals`` key, or a ``goal_met``/``meets_goal``/``met`` flag."""
    return "goals" in path or path[-1] in _GOAL_FLAGS


def _describe(script: Path) -> str:
    """The benchmark script's docstring, first paragraph, on one line."""
    doc = ast.get_docstring(ast.parse(script.read_text())) or ""
    return " ".join(doc.split("\n\n")[0].split())


def _path(path: Path_) -> str:
    return " / ".join(path).replace("|", "\\|") or "(value)"


def _value(value: Any) -> str:
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return _number(value)
    if isinstance(value, list):
        numbers = [v for v in value if isinstance(v, (int, float)) and not isinstance(v, bool)]
        if len(value) > MAX_LIST and len(numbers) == len(value):
            ordered = sorted(numbers)
            median = ordered[len(ordered) // 2]
            return (
                f"{len(value)} values, median {_number(median)} "
                f"({_number(ordered[0])} … {_number(ordered[-1])})"
            )
        if len(value) > MAX_LIST:
            return f"{len(value)} values"
        return ", ".join(_value(v) for v in value) or "(none)"
    if isinstance(value, dict):
        return "(none)"
    return str(value).replace("|", "\\|").replace("\n", " ")


def _number(value: float) -> str:
    if not math.isfinite(value):
        return str(value)
    return f"{value:.4g}"
