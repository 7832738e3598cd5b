"""``umbra bench``: run the benchmarks of the source checkout and say how each went.

Each script ``benchmarks/bench_<name>.py`` measures its baseline in the same run, prints its table
and writes ``benchmarks/results/<name>.json`` (``<name>.quick.json`` with ``--quick``, so that a
smoke run never replaces the reference figures); this command runs the ones named (all by default,
fastest first) one after the other with this interpreter, then prints one line per benchmark:
exit status, minutes taken, the results file it wrote, and whether the goals recorded in that file
were met ("missed: ..." names each one that was not). A stopped run still prints that summary.

Goals are read from the results file, however the script wrote them: a ``met``, ``goal_met`` or
``meets_goal`` boolean (the goal is named by its key); a ``goals`` mapping of names to booleans;
or a ``goals`` mapping of thresholds ``<figure>_max`` / ``<figure>_min`` next to the figure
``<figure>`` itself. A threshold whose figure is not in the file is not judged.
"""

from __future__ import annotations

import argparse
import ast
import contextlib
import json
import os
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import umbra.runtime
from umbra.connectors.errors import UserError

NAME = "bench"
HELP = "run the benchmarks (each against a baseline measured in the same run) and summarise them"
GUIDE = "docs/guide/benchmarks.md"  # the guide page this command's --help points to
#: Fastest first, so a short look comes before the long runs.
ORDER = (
    "scheduler",
    "gc_pause",
    "servo_tick",
    "pose_tool",
    "snake",
    "calib",
    "sketch",
    "console",
    "view3d",
    "links",
    "record",
    "pickup",
)


@dataclass
class Outcome:
    """How one benchmark ran: exit status (None: not finished), wall time [s], results file, and
    the goals that file says were missed."""

    name: str
    status: int | None
    seconds: float
    results: Path | None
    missed: tuple[str, ...] = ()


_MET_KEYS = ("met", "goal_met", "meets_goal")


def missed_goals(data: object, where: str = "") -> list[str]:
    """The goals a results document says were missed, each as ``name (detail)`` (see the module
    docstring for the forms read)."""
    missed: list[str] = []
    if isinstance(data, list):
        for index, item in enumerate(data):
            missed += missed_goals(item, f"{where}[{index}]")
        return missed
    if not isinstance(data, dict):
        return missed
    for key, value in data.items():
        if key in _MET_KEYS and value is False:
            detail = f"ratio {data['ratio']:.3g}" if isinstance(data.get("ratio"), float) else ""
            missed.append((where or "goal") + (f" ({detail})" if detail else ""))
        elif key == "goals" and isinstance(value, dict):
            missed += _missed_in_goals(value, data)
            nested = {name: goal for name, goal in value.items() if isinstance(goal, dict)}
            missed += missed_goals(nested, where)
        elif isinstance(value, dict | list):
            missed += missed_goals(value, key if not where else f"{where}/{key}")
    return missed


def _missed_in_goals(goals: dict[str, object], figures: dict[str, object]) -> list[str]:
    missed = []
    for name, goal in goals.items():
        if goal is False:
            missed.append(name)
            continue
        if isinstance(goal, bool) or not isinstance(goal, int | float):
            continue  # nested goals ({"met": ...}) are read by missed_goals
        for suffix, worse in (("_max", float.__gt__), ("_min", float.__lt__)):
            figure = figures.get(name.removesuffix(suffix)) if name.endswith(suffix) else None
            if not isinstance(figure, int | float) or isinstance(figure, bool):
                continue  # not judged by this suffix
            if worse(float(figure), float(goal)):
                sign = ">" if suffix == "_max" else "<"
                missed.append(f"{name.removesuffix(suffix)} {figure:.3g} {sign} {goal:g}")
    return missed


def read_missed(results: Path | None) -> tuple[str, ...]:
    """Missed goals recorded in a results file (none when there is no readable file)."""
    if results is None:
        return ()
    try:
        return tuple(missed_goals(json.loads(results.read_text())))
    except (OSError, ValueError):
        return ("results file unreadable",)


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("names", nargs="*", metavar="NAME", help="benchmarks to run (default: all)")
    parser.add_argument("--quick", action="store_true", help="each benchmark's short run")
    parser.add_argument("--list", action="store_true", help="list the benchmarks and stop")
    parser.add_argument(
        "--dir", metavar="DIR", help="benchmarks folder (default: the checkout's benchmarks/)"
    )


def benchmarks_dir(option: str | None) -> Path:
    """The folder holding ``bench_*.py``: ``option``, else ``benchmarks/`` beside the installed
    ``runtime`` package (an editable install of the checkout), else in the current folder."""
    if option:
        candidates = [Path(option)]
    else:
        checkout = Path(umbra.runtime.__file__).resolve().parents[1]
        candidates = [checkout / "benchmarks", Path("benchmarks")]
    for folder in candidates:
        if any(folder.glob("bench_*.py")):
            return folder
    raise UserError(
        f"expected benchmark scripts (bench_*.py) in {', '.join(str(c) for c in candidates)}, "
        "found none: benchmarks run from a source checkout (`pip install -e .`), or pass --dir"
    )


def available(folder: Path) -> dict[str, Path]:
    """Benchmark name -> script, in ``ORDER`` then by name."""
    found = {p.stem.removeprefix("bench_"): p for p in folder.glob("bench_*.py")}
    rank = {n: i for i, n in enumerate(ORDER)}
    return {n: found[n] for n in sorted(found, key=lambda n: (rank.get(n, len(ORDER)), n))}


def summary_line(script: Path) -> str:
    """First paragraph of the script's docstring, on one line (read, not imported)."""
    try:
        doc = ast.get_docstring(ast.parse(script.read_text()))
    except (OSError, SyntaxError, ValueError):
        return ""
    return " ".join(doc.strip().split("\n\n")[0].split()) if doc else ""


def run_one(name: str, script: Path, quick: bool) -> Outcome:
    """Run one benchmark script, its output going straight to this terminal. Ctrl-C reaches the
    script too: it stops, and the outcome's status is None."""
    results = script.parent / "results" / (f"{name}.quick.json" if quick else f"{name}.json")
    before = results.stat().st_mtime if results.exists() else None
    start = time.monotonic()
    argv = [sys.executable, str(script), *(["--quick"] if quick else [])]
    path = os.pathsep.join(p for p in (str(script.parent), os.environ.get("PYTHONPATH")) if p)
    status: int | None = None
    with contextlib.suppress(KeyboardInterrupt):  # Ctrl-C: status stays None, "stopped"
        status = subprocess.run(argv, env=dict(os.environ, PYTHONPATH=path)).returncode
    wrote = results.exists() and results.stat().st_mtime != before
    written = results if wrote else None
    return Outcome(name, status, time.monotonic() - start, written, read_missed(written))


def print_summary(outcomes: list[Outcome]) -> None:
    """One line per benchmark run: status, minutes, results file."""
    print("\nbenchmark     status        min  results")
    for o in outcomes:
        wrote = str(o.results) if o.results else "(none written)"
        print(f"{o.name:<12}  {_state(o):<12} {o.seconds / 60:4.1f}  {wrote}")
        if o.missed:
            print(f"{'':<12}  missed: {'; '.join(o.missed)}")


def _state(outcome: Outcome) -> str:
    if outcome.status is None:
        return "stopped"
    if outcome.status != 0:
        return f"failed ({outcome.status})"
    return "goal missed" if outcome.missed else "ok"


def main(args: argparse.Namespace) -> int:
    folder = benchmarks_dir(args.dir)
    scripts = available(folder)
    if args.list:
        width = max(len(n) for n in scripts)
        for name, script in scripts.items():
            print(f"{name.ljust(width)}  {summary_line(script)}")
        return 0
    unknown = [n for n in args.names if n not in scripts]
    if unknown:
        raise UserError(
            f"expected benchmark names among {', '.join(scripts)}, found {', '.join(unknown)}"
        )
    chosen = list(dict.fromkeys(args.names)) or list(scripts)
    outcomes: list[Outcome] = []
    for name in chosen:
        print(f"== bench {name}{' (quick)' if args.quick else ''}", flush=True)
        outcome = run_one(name, scripts[name], args.quick)
        outcomes.append(outcome)
        if outcome.status in (None, 130, -2):  # Ctrl-C: stop here, say what ran
            print_summary(outcomes)
            print("umbra bench: interrupted", file=sys.stderr)
            return 130
    print_summary(outcomes)
    return 0 if all(o.status == 0 and not o.missed for o in outcomes) else 1
