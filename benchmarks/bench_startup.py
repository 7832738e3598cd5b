"""What starting costs: CPU time of ``import umbra.connectors``, ``umbra --help`` and ``umbra
check graphs/tool_pickup.yaml``, against two baselines measured in the same run.

Baselines: ``python -c pass`` (the interpreter alone) and ``python -c "import
scipy.spatial.transform, scipy.stats, cv2, zenoh"`` (the numeric, vision and network stacks that a
start needs none of, and that each command below must not load). Each command runs ``--repeats``
times, interleaved with the others, in a fresh interpreter; its figure is the least user + system
CPU time [s] of its runs (``RUSAGE_CHILDREN``), the figure least disturbed by other work on the
machine. A second run of each, under ``-X importtime``, names the stacks it loaded.

    python benchmarks/bench_startup.py [--quick]
"""

from __future__ import annotations

import argparse
import resource
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.common import table, write_results  # noqa: E402

PY = sys.executable
#: The stacks a start must not load (the top-level names of their packages).
STACKS = ("scipy", "cv2", "zenoh", "matplotlib", "skimage", "fastapi", "uvicorn", "viser", "mcap")
BASELINES = {
    "python -c pass": [PY, "-c", "pass"],
    "import scipy, cv2, zenoh": [
        PY,
        "-c",
        "import scipy.spatial.transform, scipy.stats, cv2, zenoh",
    ],
}
MEASURED = {
    "import umbra.connectors": [
        PY,
        "-c",
        "import umbra.connectors; from umbra.connectors import Module, FrameTree",
    ],
    "umbra --help": [PY, "-m", "umbra.runtime.cli.main", "--help"],
    "umbra check tool_pickup": [
        PY,
        "-m",
        "umbra.runtime.cli.main",
        "check",
        "graphs/tool_pickup.yaml",
        "--quiet",
    ],
}


def cpu_seconds(argv: list[str]) -> float:
    """User + system CPU time [s] of one run of ``argv`` (from the repository's root)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    done = subprocess.run(argv, cwd=ROOT, capture_output=True, timeout=120)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(argv)} failed ({done.returncode}): {done.stderr[-2000:]!r}")
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def stacks_loaded(argv: list[str]) -> list[str]:
    """The :data:`STACKS` that ``argv`` imports (from its ``-X importtime`` report)."""
    done = subprocess.run(
        [argv[0], "-X", "importtime", *argv[1:]], cwd=ROOT, capture_output=True, text=True
    )
    names = {line.rsplit("|", 1)[-1].strip() for line in done.stderr.splitlines() if "|" in line}
    return sorted({name.split(".")[0] for name in names} & set(STACKS))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="3 runs of each instead of 15")
    parser.add_argument("--repeats", type=int, default=0, help="runs of each command")
    args = parser.parse_args()
    repeats = args.repeats or (3 if args.quick else 15)
    cases = {**BASELINES, **MEASURED}
    best = dict.fromkeys(cases, float("inf"))
    for _ in range(repeats):  # interleaved: a burst of other work touches every case alike
        for name, argv in cases.items():
            best[name] = min(best[name], cpu_seconds(argv))
    bare, stacks = best["python -c pass"], best["import scipy, cv2, zenoh"]
    loaded = {name: stacks_loaded(argv) for name, argv in MEASURED.items()}
    rows = [[name, best[name], "", "", ""] for name in BASELINES]
    rows += [
        [name, best[name], best[name] / bare, best[name] / stacks, ", ".join(loaded[name]) or "-"]
        for name in MEASURED
    ]
    print(f"least CPU time of {repeats} runs each (user + system)")
    print(table(rows, ["", "CPU s", "x python", "x stacks", "stacks loaded"]))
    figures = {
        name.replace(" ", "_").replace(".", "_"): {
            "cpu_s": best[name],
            "x_python": best[name] / bare,
            "x_stacks": best[name] / stacks,
            "stacks_loaded": loaded[name],
        }
        for name in MEASURED
    }
    path = write_results(
        "startup",
        {
            "repeats": repeats,
            "baselines_cpu_s": {name: best[name] for name in BASELINES},
            "measured": figures,
            "goals": {f"{k}_loads_no_stack": not f["stacks_loaded"] for k, f in figures.items()},
        },
        quick=args.quick,
    )
    print(f"results: {path}")


if __name__ == "__main__":
    main()
