"""When one process of a split run ends, the others finish without waiting on each other: a
process waits for the streams of processes upstream of it, not for those of processes it also
feeds (which would wait for it in turn, until the 5 s grace ran out)."""

from __future__ import annotations

import json
import os
from pathlib import Path

from tests.links.conftest import REPO, run_umbra
from umbra.runtime.graph.check import load_graph
from umbra.runtime.links.control_line import FINISH_GRACE
from umbra.runtime.links.finish_order import mutual_peers

#: `a` counts to 50 and ends the run; `b` doubles into `c`, and `c` ticks back into `b`: `b` and
#: `c` feed each other, `a` is upstream of both.
RING = """\
graph: ring
seed: 0
clock: real
processes: {a: {}, b: {}, c: {}}
modules:
  counter: {type: Counter, process: a, rate: 50, params: {stop_after: 50}}
  double: {type: Gain, process: b, params: {gain: 2.0}}
  show: {type: Printer, process: c, params: {max_rate_hz: 1}}
  ticker: {type: Counter, process: c, rate: 50}
  back: {type: Gain, process: b, params: {gain: 1.0}}
connections:
  - counter.count -> double.input
  - double.output -> show.value
  - ticker.count -> back.input
"""


def test_mutual_peers_are_the_processes_feeding_each_other(tmp_path: Path) -> None:
    (tmp_path / "ring.yaml").write_text(RING)
    ring = load_graph(str(tmp_path / "ring.yaml"))
    assert mutual_peers(ring, "a") == frozenset()
    assert mutual_peers(ring, "b") == {"c"} and mutual_peers(ring, "c") == {"b"}
    chain = load_graph(str(REPO / "graphs" / "counter_split.yaml"))
    assert mutual_peers(chain, "smart") == frozenset()  # a chain: `smart` waits for `umbra`
    pickup = load_graph(str(REPO / "graphs" / "tool_pickup.yaml"))
    assert mutual_peers(pickup, "ui") == {"umbra", "smart"}  # images one way, seeds the other


def test_a_ring_of_processes_ends_without_the_grace_and_keeps_its_tail(tmp_path: Path) -> None:
    (tmp_path / "ring.yaml").write_text(RING)
    done = run_umbra(dict(os.environ), tmp_path, "run", "ring.yaml", "--out", "out")
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    said = done.stdout + done.stderr
    assert f"input streams still open {FINISH_GRACE:.0f} s after" not in said, said[-2000:]
    links = {
        p: {s["key"]: s for s in json.loads(
            (tmp_path / "out" / f"summary-{p}.json").read_text())["links"]["subscribe"]}
        for p in ("b", "c")
    }  # fmt: skip
    counts = links["b"]["umbra/ring/counter/count"]
    assert counts["received"] == 50, counts  # upstream: waited for to the end, every sample
    # a mutual peer's stream: heard to near its end (the last sequence number heard; a loaded
    # machine may drop samples of this best-effort link on the way, which are counted missing)
    doubled = links["c"]["umbra/ring/double/output"]
    assert doubled["received"] + doubled["missing"] >= 45, doubled
