"""The hostile-input corpus (tests/hostile/corpus/manifest.yaml) through the real ``umbra`` CLI.

Every case runs ``umbra.runtime.cli.main.main(ARGV)`` in the corpus folder and checks the exit
status, that one stderr line matches the expected error, and that no traceback is printed. A few
cases run as subprocesses, to prove that nothing but the error line reaches a user's terminal.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from umbra.connectors.safe_yaml import load
from umbra.runtime.cli.main import main

CORPUS = Path(__file__).parent / "corpus"
REPO = Path(__file__).resolve().parents[2]
CASES = load((CORPUS / "manifest.yaml").read_text(encoding="utf-8"), "manifest.yaml")[1]["cases"]


def _argv(case: dict, tmp_path: Path) -> list[str]:
    fifo = tmp_path / "pipe"
    if any("{fifo}" in a for a in case["argv"]) and not fifo.exists():
        os.mkfifo(fifo)
    values = {"{tmp}": str(tmp_path), "{fifo}": str(fifo), "{repo}": str(REPO)}
    out = []
    for arg in case["argv"]:
        for key, value in values.items():
            arg = arg.replace(key, value)
        out.append(arg)
    return out


KINDS = sorted({c["id"].split("-")[0] for c in CASES})


def test_the_corpus_has_at_least_100_cases_of_every_kind() -> None:
    assert len(CASES) >= 100
    assert {"graph", "set", "run", "dh", "image", "zoom", "csv", "cameras", "pose", "fit"} <= set(
        KINDS
    )
    assert {"sketch", "posetool", "record"} <= set(KINDS)  # issue #29's files and options


def _run_case(case: dict, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> str:
    """Run one case; empty when it behaved as its manifest says, else what went wrong."""
    status = main(_argv(case, tmp_path))
    captured = capsys.readouterr()
    err = _without_plugin_warnings(captured.err)
    if "Traceback" in err:
        return f"a traceback:\n{err}"
    if status != case["status"]:
        return f"exit status {status}, expected {case['status']}:\n{err}"
    if case["error"]:  # a user error on stderr; a run's outcome (status 1) on either stream
        text = err if status == 2 else captured.out + err
        if not re.search(case["error"], text, re.MULTILINE):
            return f"no output line matches {case['error']!r}:\n{text}"
    if status == 2 and not all("error" in line for line in err.splitlines() if line.strip()):
        return f"stderr holds more than error lines:\n{err}"  # e.g. a Python repr dump
    return ""


@pytest.mark.timeout(120)
@pytest.mark.parametrize("kind", KINDS)
def test_hostile_inputs(kind: str, tmp_path: Path, monkeypatch, capsys) -> None:
    """Every case of one kind (one process, one pass: the corpus is large, the CLI fast)."""
    monkeypatch.chdir(CORPUS)
    failures = []
    for case in (c for c in CASES if c["id"].split("-")[0] == kind):
        folder = tmp_path / case["id"]
        folder.mkdir()
        problem = _run_case(case, folder, capsys)
        if problem:
            failures.append(f"{case['id']}: {problem}")
    assert not failures, "\n\n".join(failures)


def _without_plugin_warnings(err: str) -> str:
    """stderr less `umbra: warning: command ... failed to load` (a broken third-party plug-in)."""
    return "\n".join(line for line in err.splitlines() if not line.startswith("umbra: warning:"))


#: slow, and judged by no clock: CI runs these two at a time (``untimed``)
UNTIMED_SLOW = (pytest.mark.slow, pytest.mark.untimed)
SUBPROCESS_CASES = [
    pytest.param("graph-alias_bomb"),
    pytest.param("set-timeout_1e999", marks=UNTIMED_SLOW),
    pytest.param("graph-seed_5000_digits", marks=UNTIMED_SLOW),
    pytest.param("dh-latin1", marks=UNTIMED_SLOW),
    pytest.param("dh-fifo", marks=UNTIMED_SLOW),
    pytest.param("image-bomb_png", marks=UNTIMED_SLOW),
    pytest.param("zoom-xml-billion_laughs", marks=UNTIMED_SLOW),
    pytest.param("pose-collinear", marks=UNTIMED_SLOW),
    pytest.param("sketch-latin1"),
    pytest.param("record-long_record"),
    pytest.param("posetool-max_rms_nan", marks=UNTIMED_SLOW),
]


@pytest.mark.timeout(120)
@pytest.mark.parametrize("case_id", SUBPROCESS_CASES)
def test_no_traceback_reaches_the_terminal(case_id: str, tmp_path: Path) -> None:
    case = next(c for c in CASES if c["id"] == case_id)
    proc = subprocess.run(
        [sys.executable, "-m", "umbra.runtime.cli.main", *_argv(case, tmp_path)],
        cwd=CORPUS,
        capture_output=True,
        text=True,
        timeout=100,
        env={**os.environ, "PYTHONPATH": str(REPO)},
    )
    assert proc.returncode == case["status"]
    assert "Traceback" not in proc.stderr
    lines = [line for line in proc.stderr.splitlines() if not line.startswith("umbra: warning:")]
    assert lines and all(": error: " in line or "error:" in line for line in lines), proc.stderr
    assert re.search(case["error"], proc.stderr, re.MULTILINE), proc.stderr
