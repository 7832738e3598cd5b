"""A graph split over two processes by the launcher: every sample, in order, same results."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from tests.links.conftest import REPO, run_umbra
from umbra.modules.generic.recording import read_recording

GRAPH = str(REPO / "graphs" / "counter_split.yaml")


def _recording(folder: Path) -> dict[str, list[tuple[int, float]]]:
    found: dict[str, list[tuple[int, float]]] = {}
    for channel, sample in read_recording(folder / "counter_split.mcap"):
        found.setdefault(channel, []).append((sample.seq, sample.value))
    return found


def _split_run(env: dict[str, str], cwd: Path, count: int) -> Path:
    done = run_umbra(
        env, cwd, "run", GRAPH, "--out", "split", "--set", f"counter.stop_after={count}"
    )
    assert done.returncode == 0, done.stderr
    return cwd / "split"


@pytest.fixture(scope="module")
def split_and_single(
    plugin_env: dict[str, str], tmp_path_factory: pytest.TempPathFactory
) -> tuple[Path, Path]:
    cwd = tmp_path_factory.mktemp("split_and_single")
    split = _split_run(plugin_env, cwd, 200)
    done = run_umbra(
        plugin_env,
        cwd,
        "run",
        GRAPH,
        "--single-process",
        "--clock",
        "sim",
        "--out",
        "single",
        "--set",
        "counter.stop_after=200",
    )
    assert done.returncode == 0, done.stderr
    return split, cwd / "single"


@pytest.mark.parametrize(
    "count", [200, pytest.param(1000, marks=pytest.mark.slow, id="10s")], ids=["2s", "10s"]
)
def test_counter_chain_split_delivers_every_sample_in_order(
    count: int,
    plugin_env: dict[str, str],
    tmp_path_factory: pytest.TempPathFactory,
    request: pytest.FixtureRequest,
) -> None:
    if count == 200:
        folder = request.getfixturevalue("split_and_single")[0]
    else:
        folder = _split_run(plugin_env, tmp_path_factory.mktemp("long"), count)
    rec = _recording(folder)
    assert rec["count"] == [(i + 1, float(i)) for i in range(count)]
    assert rec["doubled"] == [(i + 1, 2.0 * i) for i in range(count)]
    smart = json.loads((folder / "summary-smart.json").read_text())
    (sub,) = smart["links"]["subscribe"]
    assert sub["key"] == "umbra/counter_split/counter/count"
    assert (sub["received"], sub["missing"], sub["decode_errors"]) == (count, 0, 0)
    assert len(sub["links"]) == 2  # two connections from one output: one key, one subscription
    umbra_side = json.loads((folder / "summary-umbra.json").read_text())
    (pub,) = umbra_side["links"]["publish"]
    assert (pub["sent"], pub["mode"]) == (count, "reliable/block")
    whole = json.loads((folder / "summary.json").read_text())
    assert whole["exit_code"] == 0
    assert [p["process"] for p in whole["processes"]] == ["umbra", "smart"]


def test_split_and_single_process_give_the_same_outputs(
    split_and_single: tuple[Path, Path],
) -> None:
    split, single = split_and_single
    assert _recording(split) == _recording(single)
    by_module = {}
    for folder, names in (
        (split, ("summary-umbra.json", "summary-smart.json")),
        (single, ("summary.json",)),
    ):
        modules = {}
        for name in names:
            for m in json.loads((folder / name).read_text())["modules"]:
                modules[m["module"]] = {
                    k: m[k] for k in ("calls", "sent", "recorded", "seen") if k in m
                }
        by_module[folder.name] = modules
    assert by_module["split"] == by_module["single"]
    assert by_module["split"]["record"] == {"calls": 200, "recorded": 400}


def test_the_cpu_latency_asked_on_the_command_line_is_held_by_every_process(
    plugin_env: dict[str, str], tmp_path: Path
) -> None:
    from umbra.runtime.realtime import PM_QOS_FILE

    done = run_umbra(
        plugin_env,
        tmp_path,
        "run",
        GRAPH,
        "--out",
        "rt",
        "--set",
        "counter.stop_after=20",
        "--cpu-latency-us",
        "0",
    )
    assert done.returncode == 0, done.stderr
    can = os.access(PM_QOS_FILE, os.W_OK)
    for process in ("umbra", "smart"):
        summary = json.loads((tmp_path / "rt" / f"summary-{process}.json").read_text())
        assert summary["realtime"]["cpu_latency_us"] == 0
        assert summary["realtime"]["held"] is can
    said = "holding every CPU's wake-up latency at most 0 µs" if can else "not held"
    assert done.stderr.count(said) == 2, done.stderr


def test_a_bad_cpu_latency_is_refused_before_anything_starts(
    plugin_env: dict[str, str], tmp_path: Path
) -> None:
    done = run_umbra(plugin_env, tmp_path, "run", GRAPH, "--cpu-latency-us", "-1")
    assert done.returncode == 2
    assert "--cpu-latency-us must be from 0 to 2000000000 microseconds, found -1" in done.stderr
    assert "Traceback" not in done.stderr and "started process" not in done.stderr
