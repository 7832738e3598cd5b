"""What umbra writes as JSON parses under the standard: a measurement that was not made (NaN, an
infinite age) is ``null``, never Python's ``NaN``, which JavaScript's ``JSON.parse``, ``jq`` and
msgspec's strict decoder (the independent parser here) refuse."""

from __future__ import annotations

from pathlib import Path

import msgspec
import numpy as np
import pytest

from umbra.connectors.cli_support import print_json
from umbra.connectors.json_text import finite, json_text
from umbra.connectors.messages import ZoomState
from umbra.runtime.cli.cmd_echo import _print
from umbra.runtime.links.observe import Observed
from umbra.runtime.run import write_summary
from umbra.runtime.stats import ModuleStats, RunResult

NAN, INF = float("nan"), float("inf")


def test_a_run_summary_with_measurements_not_made_is_standard_json(tmp_path: Path) -> None:
    world = ModuleStats("world", "World")
    world.extra = {
        "grasp_distance_mm": NAN,
        "first_moved_at": np.float64(NAN),
        "path": np.array([[1.0, NAN], [INF, 2.0]]),
        "ages": (0.5, -INF),
        "stages": {"grab": {"error_mm": NAN, "done": True}},
    }
    result = RunResult("smart", 0, "no grasp", 10, 1.0, 1.0, [world], np.array([1e-4, 2e-4]))
    path = write_summary(result, tmp_path, "smart")
    summary = msgspec.json.decode(path.read_bytes())  # strict: NaN would be refused
    extra = next(m for m in summary["modules"] if m["module"] == "world")
    assert extra["grasp_distance_mm"] is None and extra["first_moved_at"] is None
    assert extra["path"] == [[1.0, None], [None, 2.0]]
    assert extra["ages"] == [0.5, None]
    assert extra["stages"] == {"grab": {"error_mm": None, "done": True}}
    assert summary["reason"] == "no grasp" and summary["lateness_p99_ms"] > 0


def test_echo_and_print_json_lines_are_standard_json(capsys: pytest.CaptureFixture[str]) -> None:
    unknown = ZoomState(stamp=1.0, zoom=NAN, raw=-1, moving=False)  # a camera not yet read
    _print(Observed("run/sony/zoom", "sample", unknown, "ZoomState", 40, "", 0.0), as_json=True)
    print_json({"age_s": INF, "gain": np.float32(0.5), "poses": np.zeros((1, 2))})
    lines = capsys.readouterr().out.splitlines()
    echoed, printed = (msgspec.json.decode(line) for line in lines)
    assert echoed["zoom"] is None and echoed["raw"] == -1
    assert printed == {"age_s": None, "gain": 0.5, "poses": [[0.0, 0.0]]}


def test_finite_keeps_every_finite_value_and_refuses_what_is_not_json() -> None:
    value = {"a": [1, 2.5, "x", None, True], "b": {"c": np.int64(3)}}
    assert finite(value) == {"a": [1, 2.5, "x", None, True], "b": {"c": 3}}
    assert json_text(-0.0) == "-0.0"
    with pytest.raises(TypeError, match="object is not JSON"):
        json_text(object())
    assert json_text(object(), default=lambda o: NAN) == "null"
