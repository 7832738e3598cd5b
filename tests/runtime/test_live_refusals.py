"""A value set live is judged by the module's own declaration: every tunable parameter of every
registered module type, given values out of its bounds, of a wrong length or sign, or of a wrong
type, through the live server's parameter handler (what a Foxglove client's ``setParameters``
reaches), is refused with the model's reason and never reaches the module; a good value is
applied between steps. A module whose ``retune`` fails all the same keeps its parameters and the
run goes on. In a graph file, the same values are refused by ``umbra check`` and ``umbra run``
(exit 2)."""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

import pytest

from tests.runtime.param_draws import outside
from umbra.connectors.module import Module
from umbra.connectors.params import (
    Bounds,
    Parameters,
    element_bounds,
    is_tunable,
    param,
    with_change,
)
from umbra.runtime.cli.main import main
from umbra.runtime.graph.check import check_text
from umbra.runtime.harness import ModuleHarness
from umbra.runtime.live.parameters import ParameterTable
from umbra.runtime.registry import Registry
from umbra.runtime.tuning import Tuner

REGISTRY = Registry()
REPO = Path(__file__).resolve().parents[2]

#: One module of each type that declares a tunable parameter, wired as a graph must be.
GRAPH = """
graph: tunables
modules:
  src: {type: Constant, rate: 50, params: {value: 2.0}}
  gain: {type: Gain}
  camera: {type: DigiCam, rate: 10}
  snake: {type: vsSnake}
  servo: {type: vsServo}
  plot: {type: StatusPlot}
connections:
  - src.output -> gain.input
  - camera.image -> snake.image
  - snake.contour -> servo.contour
  - servo.status -> plot.status
"""


def tunables() -> list[tuple[str, str]]:
    """``(type, parameter)`` of every tunable parameter of every registered type."""
    return [
        (name, p)
        for name in REGISTRY.names()
        for p in REGISTRY.require(name).Params.model_fields
        if is_tunable(REGISTRY.require(name).Params, p)
    ]


def bad_values(params: type[Parameters], name: str) -> list[Any]:
    """Out of bounds, wrong lengths, wrong signs (from the declaration), and wrong types."""
    field = params.model_fields[name]
    kind = field.annotation
    wrong = [1.0] if getattr(kind, "__origin__", None) is dict else {"a": 1}
    values: list[Any] = [wrong]  # a wrong type for every declaration
    if kind in (int, float):
        values += [*outside(kind, Bounds.of(field.metadata)), "fast", [1.0]]
    elif getattr(kind, "__origin__", None) is list:
        default = list(field.get_default(call_default_factory=True))
        each = element_bounds(kind)
        if each is not None:
            values += [[v] * len(default) for v in outside(float, each)]
        lengths = Bounds.of(field.metadata)
        if lengths.max_length is not None:
            values.append([*default, default[-1]])
        if lengths.min_length:
            values.append(default[:-1])
        values.append(["x"] * max(len(default), 1) if kind != list[str] else [[1.0]])
    elif kind is str:
        values.append([1.0])
    return values


@pytest.fixture
def live() -> Any:
    """The graph's plan, its started modules, their tuner and the live server's table."""
    plan = check_text(GRAPH, "tunables.yaml", REGISTRY)
    harnesses = {
        name: ModuleHarness(m.cls, m.spec.params, name=name).start()
        for name, m in plan.modules.items()
    }
    modules = {name: h.module for name, h in harnesses.items()}
    tuner = Tuner(modules, logging.getLogger("test.tuning"))
    table = ParameterTable(plan)
    table.serve_locally(tuner, list(modules))
    yield plan, modules, tuner, table
    for h in harnesses.values():
        h.stop()


def test_the_graph_holds_every_type_with_a_tunable_parameter() -> None:
    plan = check_text(GRAPH, "tunables.yaml", REGISTRY)
    held = {m.cls.type_name() for m in plan.modules.values()}
    assert {t for t, _ in tunables()} <= held
    assert ("vsServo", "gains") in tunables() and ("vsSnake", "tension") in tunables()


def test_every_bad_live_value_is_refused_with_the_models_reason(live: Any) -> None:
    plan, modules, tuner, table = live
    by_type = {m.cls.type_name(): name for name, m in plan.modules.items()}
    refused = 0
    for type_name, key in tunables():
        module = by_type[type_name]
        before = modules[module].params
        for value in bad_values(type(before), key):
            with pytest.raises(ValueError) as model:
                with_change(before, key, value)
            answer, refusals = table.set("viewer #1", [(f"{module}.{key}", value)])
            assert len(refusals) == 1, (module, key, value, refusals)
            assert str(model.value) in refusals[0], (refusals[0], str(model.value))
            assert answer[0]["name"] == f"{module}.{key}"  # the value kept, told back
            refused += 1
        assert not tuner.pending  # nothing queued for the module
        tuner.apply(0.0)
        assert modules[module].params is before
    assert refused >= 30


def test_the_servo_gains_of_the_issue_are_refused_live_and_a_good_change_is_applied(
    live: Any,
) -> None:
    _plan, modules, tuner, table = live
    _, refusals = table.set("viewer #1", [("servo.gains", [-2, -2, -2, -2])])
    assert refusals == [
        "parameter `servo.gains` not changed: parameter `gains.0`: "
        "Input should be greater than or equal to 0, found -2; parameter `gains.1`: "
        "Input should be greater than or equal to 0, found -2; parameter `gains.2`: "
        "Input should be greater than or equal to 0, found -2; parameter `gains.3`: "
        "Input should be greater than or equal to 0, found -2"
    ]
    answer, refusals = table.set("viewer #1", [("servo.gains", [0.5, 0.5, 0.4, 0.5])])
    assert refusals == [] and answer == [{"name": "servo.gains", "value": [0.5, 0.5, 0.4, 0.5]}]
    tuner.apply(1.0)
    servo = modules["servo"]
    assert servo.params.gains == [0.5, 0.5, 0.4, 0.5]
    assert servo.stages.gains.gains == (0.5, 0.5, 0.4, 0.5)


class _Fragile(Module):
    """Takes any gain its model allows, and fails to rebuild above 5 (a module defect)."""

    class Params(Parameters):
        gain: float = param(1.0, "factor", tunable=True)

    def start(self) -> None:
        self.built = self.params.gain

    def retune(self, old: Parameters) -> None:
        if self.params.gain > 5:
            raise ZeroDivisionError("cannot rebuild")
        self.built = self.params.gain


def test_a_retune_that_fails_is_rolled_back_and_the_run_goes_on(
    caplog: pytest.LogCaptureFixture,
) -> None:
    with ModuleHarness(_Fragile, {}, name="frag") as h:
        tuner = Tuner({"frag": h.module}, logging.getLogger("test.tuning"))
        assert tuner.request("frag", "gain", 9.0, "viewer #1") == ""
        with caplog.at_level(logging.ERROR, "test.tuning"):
            tuner.apply(0.0)  # does not raise
        assert h.module.params.gain == 1.0 and h.module.built == 1.0
        assert "refused and rolled back" in caplog.text and "ZeroDivisionError" in caplog.text
        assert tuner.request("frag", "gain", 3.0, "viewer #1") == ""
        tuner.apply(0.1)
        assert h.module.params.gain == 3.0 and h.module.built == 3.0


def test_check_and_run_refuse_the_servo_gains_in_a_file_with_exit_2(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    text = (REPO / "graphs" / "tool_pickup.yaml").read_text()
    assert text.count("settle_frames: 10,") == 1
    graph = tmp_path / "drifted.yaml"  # the pick-up, with the gains of the issue
    graph.write_text(
        text.replace("settle_frames: 10,", "gains: [-2, -2, -2, -2], settle_frames: 10,")
    )
    assert main(["check", str(graph)]) == 2
    said = capsys.readouterr().err
    assert "drifted.yaml:" in said
    assert "parameter `gains.0` of `servo`: Input should be greater than or equal to 0" in said
    out = str(tmp_path / "run")
    assert main(["run", str(graph), "--single-process", "--clock", "sim", "--out", out]) == 2
    said = capsys.readouterr().err
    assert "parameter `gains.0` of `servo`" in said and "Traceback" not in said
