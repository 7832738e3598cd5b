"""Which run a tool attaches to, from the run files in a user folder of the test's own: the run
its ID names, else the newest run of the graph; an unknown ID or several graphs are refused
naming the runs; an observation says when its run's processes are gone and delivers nothing
after. Real run files and real processes (a sleeping child stands for a run's process)."""

from __future__ import annotations

import argparse
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

from umbra.connectors.errors import UserError
from umbra.runtime.launcher import run_identity
from umbra.runtime.links.config import Endpoints, build_config
from umbra.runtime.links.observe import Observation, choose_run, find_run, local_runs
from umbra.runtime.links.runs import (
    BY_HAND,
    RunFile,
    checked_run_id,
    new_run_id,
    write_run_file,
)
from umbra.runtime.links.session import open_session


@pytest.fixture
def folder(tmp_path: Path) -> Path:
    where = tmp_path / "user"
    where.mkdir(mode=0o700)
    return where


@pytest.fixture
def pids() -> Iterator[list[int]]:
    """Three live processes that stand for processes of runs (a run file is named by its pid)."""
    children = [
        subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"]) for _ in range(3)
    ]
    yield [c.pid for c in children]
    for child in children:
        child.kill()
        child.wait()


def _file(
    folder: Path,
    run_id: str,
    process: str,
    pid: int,
    *,
    graph: str = "pickup",
    run_started: float = 0.0,
    started: float = 1000.0,
    of: int = 2,
) -> None:
    write_run_file(
        RunFile(
            graph=graph,
            prefix=f"umbra/{graph}",
            process=process,
            pid=pid,
            listen=["tcp/127.0.0.1:1"],
            access="credentials",
            publish_all=True,
            outputs=[],
            started=started,
            run_id=run_id,
            launcher=pid,
            run_started=run_started,
            run_processes=of,
        ),
        folder,
    )


def test_the_run_named_else_the_newest_and_an_unknown_id_names_the_runs(
    folder: Path, pids: list[int]
) -> None:
    # the older run's processes wrote their files last (they were slow to build): the run's
    # start, not its files', orders the runs
    _file(folder, "old", "umbra", pids[0], run_started=100.0, started=200.0)
    _file(folder, "old", "smart", pids[1], run_started=100.0, started=201.0)
    _file(folder, "new", "umbra", pids[2], run_started=150.0, started=151.0)
    assert [r.run_id for r in local_runs(folder)] == ["old", "new"]
    newest = choose_run(None, folder)
    assert newest.run_id == "new" and not newest.complete and newest.expected == 2
    assert choose_run("pickup", folder, "old").run_id == "old"
    assert choose_run("umbra/pickup", folder, "old").complete
    found = find_run("old", None, folder)
    assert found is not None and len(found.processes) == 2
    assert find_run("nope", None, folder) is None
    with pytest.raises(UserError) as refused:
        choose_run(None, folder, "nope")
    said = str(refused.value)
    assert "\n" not in said and said.startswith("--run: expected a run on this host")
    assert "found no run `nope`; runs: old (graph pickup, launcher pid" in said
    assert "; new (graph pickup" in said and "1 of 2 processes" in said


def test_several_graphs_are_named_not_guessed(folder: Path, pids: list[int]) -> None:
    _file(folder, "a1", "umbra", pids[0], graph="pickup", of=1)
    _file(folder, "b1", "umbra", pids[1], graph="snake", of=1)
    with pytest.raises(UserError) as refused:
        choose_run(None, folder)
    said = str(refused.value)
    assert "found 2: pickup (prefix umbra/pickup); snake (prefix umbra/snake)" in said
    assert "--graph NAME" in said and "a1 (graph pickup" in said and "b1 (graph snake" in said
    assert choose_run("snake", folder).run_id == "b1"
    assert choose_run(None, folder, "a1").graph == "pickup"


def test_a_run_whose_processes_are_gone_is_not_chosen(folder: Path) -> None:
    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone.wait()
    _file(folder, "dead", "umbra", gone.pid, of=1)
    assert local_runs(folder) == []
    with pytest.raises(UserError, match="no graph runs on this host"):
        choose_run(None, folder)


def test_an_observation_says_when_its_run_ended_and_delivers_nothing_after(
    folder: Path,
) -> None:
    child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        _file(folder, "r1", "umbra", child.pid, of=1)
        (run,) = local_runs(folder)
        session = open_session(build_config(Endpoints()))
        observation = Observation(session, run.prefix, run, keys=["umbra/pickup/counter/count"])
        got: list[str] = []
        told = threading.Event()
        observation.when_ended(told.set)
        observation.subscribe(lambda o: got.append(o.key))
        session.put("umbra/pickup/counter/count", b"x")  # local delivery: the run is alive
        assert not observation.ended.is_set()
        child.kill()
        child.wait()
        assert told.wait(5) and observation.ended.is_set()
        session.put("umbra/pickup/counter/count", b"y")
        observation.close()
    finally:
        child.kill()
        child.wait()
    assert got == ["umbra/pickup/counter/count"]


def test_run_ids_are_new_checked_and_never_taken_twice(
    folder: Path, pids: list[int], monkeypatch: pytest.MonkeyPatch
) -> None:
    made = {new_run_id("pickup") for _ in range(20)}
    assert len(made) == 20 and all(checked_run_id(r) == r for r in made)
    assert all(r.startswith("pickup-") for r in made)
    for bad in ("", "a/b", "-x", "a b", "x" * 129):
        with pytest.raises(UserError, match="--run-id: expected a run ID"):
            checked_run_id(bad)
    plan = argparse.Namespace(spec=argparse.Namespace(name="pickup"))
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(folder.parent))
    user = folder.parent / "umbra"
    user.mkdir(mode=0o700)
    _file(user, "taken", "umbra", pids[0])
    with pytest.raises(
        UserError, match="--run-id: expected an ID no live run holds, found `taken`"
    ):
        run_identity(plan, argparse.Namespace(run_id="taken", process=None))  # type: ignore[arg-type]
    assert run_identity(plan, argparse.Namespace(run_id="free", process=None)) == "free"  # type: ignore[arg-type]
    assert run_identity(plan, argparse.Namespace(run_id=None, process="smart")) == BY_HAND  # type: ignore[arg-type]
    assert run_identity(plan, argparse.Namespace(run_id="taken", process="smart")) == "taken"  # type: ignore[arg-type]
