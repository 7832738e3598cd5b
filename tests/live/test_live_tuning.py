"""A viewer changes a tunable parameter of a module in another process of a running graph, with
Foxglove's own npm client (``@foxglove/ws-protocol``): the change crosses the run's parameter
link, the module's output changes from then on, and the change is logged and recorded; a
parameter that is not tunable and a value the model refuses are refused with a message."""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest
from mcap.reader import make_reader

from tests.live.helpers import REPO, LiveRun, install_client, needs_node, run_tune, wait_joined
from umbra.connectors.codec import Codec
from umbra.connectors.messages import ParamChange
from umbra.runtime.links.acl import param_key
from umbra.runtime.links.observe import Observation
from umbra.runtime.tuning import CHANGES_TOPIC

pytestmark = pytest.mark.slow

GRAPH = REPO / "graphs" / "counter_split.yaml"


@pytest.fixture(scope="module")
def tune_js(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return install_client(tmp_path_factory.mktemp("npm")).parent / "tune.js"


def _intrude(run: LiveRun) -> None:
    """The run's observer (any tool of this user) puts a change on the servo process's key:
    the graph's access rules let only the live server's process put there."""
    observer = Observation.open("counter_split", run_id=run.run_id)
    try:
        change = ParamChange(module="double", param="gain", value="7", by="intruder", seq=1)
        key = param_key(observer.prefix, "smart")
        for _ in range(20):
            observer.session.put(key, Codec().encode(change))
            time.sleep(0.05)
    finally:
        observer.close()


@needs_node
def test_a_viewer_tunes_a_module_of_another_process(tune_js: Path, tmp_path: Path) -> None:
    out = tmp_path / "run"
    run = LiveRun(str(GRAPH), out, "--duration", "25", "--record", "--set", "counter.stop_after=0")
    try:
        wait_joined(run)
        changes = [
            {"at": 2.0, "name": "double.gain", "value": 5},
            {"at": 2.0, "name": "counter.stop_after", "value": 3},  # not tunable
            {"at": 2.0, "name": "double.bias", "value": "fast"},  # not a number
        ]
        report = run_tune(tune_js, run.url, 20.0, "/counter/count,/double/output", changes)
        _intrude(run)
        assert run.wait(90) == 0, run.text()[-3000:]
    finally:
        run.stop()
    assert report.get("error") is None, report["error"]
    params = report["parameters"]
    assert params["double.gain"] == 2.0 and params["counter.stop_after"] == 0
    assert report["answers"]["set0"] == [{"name": "double.gain", "value": 5}], report["statuses"]
    assert report["answers"]["set1"] == [{"name": "counter.stop_after", "value": 0}]
    assert report["answers"]["set2"] == [{"name": "double.bias", "value": 0.0}]
    said = sorted(s["message"] for s in report["statuses"])
    assert len(said) == 2, said
    assert "counter.stop_after" in said[0] and "not declared tunable" in said[0]
    assert "double.bias" in said[1] and "valid number" in said[1]

    # the doubled count, matched to the count by stamp: x2, then x5 from the change on
    counts = {m["stamp"]: m["value"] for _t, m in report["samples"]["/counter/count"]}
    ratios = [
        m["value"] / counts[m["stamp"]]
        for _t, m in report["samples"]["/double/output"]
        if counts.get(m["stamp"])
    ]
    assert ratios and ratios[0] == 2.0 and ratios[-1] == 5.0, ratios[:3] + ratios[-3:]
    switched = [i for i in range(1, len(ratios)) if ratios[i] != ratios[i - 1]]
    assert len(switched) == 1 and set(ratios) == {2.0, 5.0}  # once, and for good

    log = run.text()
    assert "[smart]" in log and "param double.gain 2.0 -> 5.0 by foxglove viewer #1" in log
    assert "intruder" not in log  # never delivered, so never even refused
    with open(out / "recording.mcap", "rb") as f:
        recorded = [
            json.loads(m.data) for _s, _c, m in make_reader(f).iter_messages(topics=[CHANGES_TOPIC])
        ]
    assert [(r["module"], r["param"], r["old"], r["value"]) for r in recorded] == [
        ("double", "gain", "2.0", "5.0")
    ]
