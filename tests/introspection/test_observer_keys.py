"""``umbra keys --observer``: an observer certificate whose rules let it read the outputs named
and nothing else, used by ``umbra topics/echo`` against a run with mutual TLS."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from tests.introspection.helpers import COUNTER, json_lines, running, umbra_cli
from tests.links.conftest import Running
from umbra.runtime.links.config import free_loopback_ports
from umbra.runtime.links.observe import Observation, Observed

# whole runs of umbra in subprocesses, seconds each: in CI with -m slow (a short default run)
pytestmark = pytest.mark.slow

COUNT, DOUBLE = "umbra/counter_split/counter/count", "umbra/counter_split/double/output"


def test_an_observer_certificate_reads_its_keys_and_nothing_else(
    umbra: Callable[..., Running], plugin_env: dict[str, str], tmp_path: Path
) -> None:
    made = umbra_cli(
        plugin_env, "keys", COUNTER, "--out", "keys", "--observer", "watcher=counter/count",
        cwd=tmp_path,
    )  # fmt: skip
    assert made.returncode == 0, made.stderr
    assert "umbra topics --zenoh-config keys/observer@watcher.json5" in made.stderr
    bad = umbra_cli(
        plugin_env, "keys", COUNTER, "--out", "k2", "--observer", "w=nope/x", cwd=tmp_path
    )
    assert bad.returncode == 2 and "expected outputs of graph `counter_split`" in bad.stderr
    # as across hosts: each process started by hand with its certificate and TLS endpoints
    p1, p2 = free_loopback_ports(2)
    common = ("--zenoh-config", "keys/", "--out", "out", "--duration", "300", "--publish-all")
    common += ("--quiet", "--set", "counter.stop_after=100000")
    run = umbra("run", COUNTER, "--process", "umbra", "--listen", f"tls/127.0.0.1:{p1}", *common)
    smart = umbra(
        "run", COUNTER, "--process", "smart", "--listen", f"tls/127.0.0.1:{p2}",
        "--connect", f"tls/127.0.0.1:{p1}", *common,
    )  # fmt: skip
    graph = running([run, smart], plugin_env)
    assert graph.access == "config"
    connect = [arg for p in graph.processes for e in p.listen for arg in ("--connect", e)]
    assert all(e.startswith("tls/") for p in graph.processes for e in p.listen)
    config = ("--zenoh-config", "keys/observer@watcher.json5")

    topics = umbra_cli(
        plugin_env, "topics", "--json", "--window", "2", *config, *connect, cwd=tmp_path
    )
    assert topics.returncode == 0, topics.stderr
    (row,) = json_lines(topics.stdout)
    assert row["key"] == COUNT and row["producer"] == "umbra" and row["type"] == "Scalar"
    assert 50 < row["rate_hz"] < 150, row
    echo = umbra_cli(plugin_env, "echo", "double/output", *config, *connect, cwd=tmp_path)
    assert echo.returncode == 2 and f"readable: {COUNT}" in echo.stderr
    local = umbra_cli(plugin_env, "topics", cwd=tmp_path)  # no certificate: told how
    assert local.returncode == 2 and "--observer NAME" in local.stderr

    # the rules, not the command, hold it: a subscription to the other output gets nothing
    observer = Observation.open(
        zenoh_config=str(tmp_path / "keys" / "observer@watcher.json5"),
        connect=[e for p in graph.processes for e in p.listen],
    )
    got: dict[str, list[Observed]] = {COUNT: [], DOUBLE: []}
    lock = threading.Lock()

    def on_sample(o: Observed) -> None:
        with lock:
            got[o.key].append(o)

    try:
        observer.subscribe(on_sample, COUNT)
        observer.subscribe(on_sample, DOUBLE)
        time.sleep(2.0)  # a window: the granted key streams, the denied one stays silent
    finally:
        observer.close()
    assert len(got[COUNT]) > 50 and got[DOUBLE] == []


def test_on_one_host_an_observer_certificate_joins_a_launched_tls_run(
    umbra: Callable[..., Running], plugin_env: dict[str, str], tmp_path: Path
) -> None:
    """Under the launcher a TLS run also has per-run passwords: the observer shows both its
    certificate and the run's observer password (from the run files), and finds the endpoints."""
    made = umbra_cli(
        plugin_env, "keys", COUNTER, "--out", "keys", "--observer", "all", cwd=tmp_path
    )
    assert made.returncode == 0, made.stderr
    run = umbra(
        "run", COUNTER, "--zenoh-config", "keys/", "--out", "out", "--duration", "300",
        "--publish-all", "--quiet", "--set", "counter.stop_after=100000",
    )  # fmt: skip
    graph = running(run, plugin_env)
    assert graph.access == "config" and graph.processes[0].observer is not None
    topics = umbra_cli(
        plugin_env, "topics", "--json", "--zenoh-config", "keys/observer@all.json5", cwd=tmp_path
    )
    assert topics.returncode == 0, topics.stderr
    rows = {r["key"]: r for r in json_lines(topics.stdout)}
    assert set(rows) == {COUNT, DOUBLE}
    assert all(r["samples"] > 20 and r["drops"] >= 0 for r in rows.values()), rows
