"""``umbra bench`` runs benchmark scripts as a user would: real subprocesses, real result files."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from umbra.runtime.cli.cmd_bench import ORDER, available, benchmarks_dir

FAKE = '''"""A fake benchmark: {what}."""
import json, sys, pathlib
quick = "--quick" in sys.argv
out = pathlib.Path(__file__).parent / "results"
out.mkdir(exist_ok=True)
print("table of {name}", "quick" if quick else "full")
{body}
'''


def _fake(folder: Path, name: str, body: str, what: str = "measures nothing") -> None:
    (folder / f"bench_{name}.py").write_text(FAKE.format(name=name, body=body, what=what))


def _bench(*args: str, timeout: float = 60) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "umbra.runtime.cli.main", "bench", *args],
        capture_output=True,
        text=True,
        timeout=timeout,
    )


def test_the_checkout_benchmarks_are_found_fastest_first() -> None:
    folder = benchmarks_dir(None)
    names = list(available(folder))
    ranked = [n for n in ORDER if n in names]
    assert len(ranked) >= 10 and names[: len(ranked)] == ranked  # ORDER first, fastest first
    assert names[len(ranked) :] == sorted(set(names) - set(ORDER))  # newer ones after, by name
    assert set(names) == {p.stem.removeprefix("bench_") for p in folder.glob("bench_*.py")}
    listed = _bench("--list")
    assert listed.returncode == 0
    assert [line.split()[0] for line in listed.stdout.splitlines()] == names
    assert re.search(r"^pickup +Tool pick-up trial sets: randomized grabs", listed.stdout, re.M)


def test_runs_each_named_benchmark_and_summarises_status_and_results(tmp_path: Path) -> None:
    write = 'name = "good.quick.json" if quick else "good.json"\n'
    _fake(tmp_path, "good", write + 'json.dump({"quick": quick}, open(out / name, "w"))')
    _fake(tmp_path, "bad", "sys.exit(3)", what="fails")
    done = _bench("good", "bad", "--quick", "--dir", str(tmp_path))
    assert done.returncode == 1  # one benchmark failed
    assert "table of good quick" in done.stdout and "table of bad quick" in done.stdout
    lines = {line.split()[0]: line for line in done.stdout.splitlines()[-2:]}
    quick_file = tmp_path / "results" / "good.quick.json"
    assert " ok " in lines["good"] and str(quick_file) in lines["good"]
    assert "failed (3)" in lines["bad"] and "(none written)" in lines["bad"]
    assert json.loads(quick_file.read_text()) == {"quick": True}
    assert not (tmp_path / "results" / "good.json").exists()
    only_good = _bench("good", "--dir", str(tmp_path))
    assert only_good.returncode == 0 and "table of good full" in only_good.stdout
    assert str(tmp_path / "results" / "good.json") in only_good.stdout.splitlines()[-1]
    assert json.loads(quick_file.read_text()) == {"quick": True}  # the quick figures stay apart


def test_bad_names_and_missing_folders_are_user_errors(tmp_path: Path) -> None:
    _fake(tmp_path, "good", "pass")
    wrong = _bench("good", "nope", "--dir", str(tmp_path))
    assert wrong.returncode == 2 and "Traceback" not in wrong.stderr
    assert "expected benchmark names among good, found nope" in wrong.stderr
    empty = _bench("--dir", str(tmp_path / "missing"))
    assert empty.returncode == 2 and "Traceback" not in empty.stderr
    assert "found none" in empty.stderr and "--dir" in empty.stderr


@pytest.mark.skipif(os.name != "posix", reason="sends SIGINT to a process group")
def test_ctrl_c_stops_and_still_prints_what_ran(tmp_path: Path) -> None:
    _fake(tmp_path, "first", "pass")
    _fake(
        tmp_path,
        "second",
        "import time\ntry:\n    print('started', flush=True)\n    time.sleep(60)\n"
        "except KeyboardInterrupt:\n    sys.exit(130)",
    )
    _fake(tmp_path, "third", "pass")
    argv = [sys.executable, "-m", "umbra.runtime.cli.main", "bench", "first", "second", "third"]
    proc = subprocess.Popen(
        [*argv, "--dir", str(tmp_path)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,  # its own process group, as a terminal's Ctrl-C would reach it
    )
    assert proc.stdout is not None
    deadline = time.monotonic() + 30
    for line in proc.stdout:
        if line.startswith("started") or time.monotonic() > deadline:
            break
    os.killpg(proc.pid, signal.SIGINT)
    rest, err = proc.communicate(timeout=30)
    assert proc.returncode == 130
    assert "interrupted" in err and "Traceback" not in err
    summary = {line.split()[0]: line for line in rest.splitlines() if line.split()}
    assert " ok " in summary["first"]
    assert "second" in summary and " ok " not in summary["second"]
    assert "third" not in summary  # not started after the stop


def test_a_missed_goal_is_not_ok(tmp_path: Path) -> None:
    """A benchmark that exits 0 but records a missed goal (``p99 ratio 2.61 (goal <= 1.2)``)."""
    _fake(
        tmp_path,
        "slow",
        'json.dump({"p99_ratio": 2.61, "goals": {"p99_ratio_max": 1.2}}, '
        'open(out / "slow.json", "w"))',
    )
    _fake(
        tmp_path,
        "links",
        'json.dump({"hosts": {"a": {"goals": {"small": {"ratio": 1.34, "met": False}}}}}, '
        'open(out / "links.json", "w"))',
    )
    _fake(tmp_path, "fine", 'json.dump({"goal_met": True}, open(out / "fine.json", "w"))')
    done = _bench("slow", "links", "fine", "--dir", str(tmp_path))
    assert done.returncode == 1
    summary = done.stdout.split("benchmark     status")[1]
    assert "slow          goal missed" in summary and "missed: p99_ratio 2.61 > 1.2" in summary
    assert "links         goal missed" in summary
    assert "missed: hosts/a/small (ratio 1.34)" in summary
    assert "fine          ok" in summary
