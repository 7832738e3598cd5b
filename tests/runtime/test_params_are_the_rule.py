"""A module's ``Params`` declaration is its whole rule: for every registered module type, whatever
its model accepts (as ``umbra check`` uses it), the module's ``start`` accepts; whatever the model
refuses, ``umbra check`` refuses in a graph file, at that module's parameters.

Values are drawn from each declaration's own bounds (hypothesis): inside them, just outside,
wrong lengths, wrong signs, wrong types, one parameter at a time over the module's simulated
settings. Modules that serve a page listen on a free port; devices are their simulations.
"""

from __future__ import annotations

import numpy as np
import pydantic
import pytest
from hypothesis import HealthCheck, given, settings

from umbra.connectors.errors import CheckFailed
from umbra.runtime.graph.check import check_text
from umbra.runtime.harness import ModuleHarness
from umbra.runtime.registry import Registry

from .param_draws import draws, yaml_value

REGISTRY = Registry()
TYPES = sorted(REGISTRY.names())

#: A module thread that dies on a value the model took is a failure too (View3D's pusher did, on
#: a max_fps of 1e-300: its wait overflowed the OS's time).
pytestmark = pytest.mark.filterwarnings("error::pytest.PytestUnhandledThreadExceptionWarning")

#: Settings each type runs with in the test (its simulation, no fixed port, no page).
BASE: dict[str, dict[str, object]] = {
    "OperatorConsole": {"serve": False},
    "View3D": {"port": 0},
    "SketchPage": {"port": 0},
}
#: Parameters kept at their base value when drawn inside their bounds (a port: the test takes
#: a free one; the value is still drawn outside the bounds and with wrong types).
KEEP = {"port"}

#: The graph's static frames: the pick-up's, and a PTU on the base.
FRAMES = {
    "base->table": [0.0, 0.0, 0.25],
    "flange->tool": [0.0, 0.0, 0.14],
    "tool->camera": [0.0, 0.0, -0.12],
    "base->ptu": [0.5, 0.0, 0.3],
}


def _harness_frames() -> dict[str, np.ndarray]:
    out = {}
    for key, xyz in FRAMES.items():
        T = np.eye(4)
        T[:3, 3] = xyz
        out[key] = T
    return out


def graph_text(type_name: str, params: dict[str, object]) -> str:
    """A graph of one module ``m`` of ``type_name`` with ``params``."""
    frames = "".join(f"  {k}: {{xyz: {yaml_value(v)}}}\n" for k, v in FRAMES.items())
    values = ", ".join(f"{k}: {yaml_value(v)}" for k, v in params.items())
    return (
        f"graph: g\nframes:\n{frames}modules:\n"
        f"  m: {{type: {type_name}, rate: 50, params: {{{values}}}}}\n"
    )


def param_problems(type_name: str, params: dict[str, object]) -> list[str]:
    """The problems ``umbra check`` reports at the module's parameters."""
    try:
        check_text(graph_text(type_name, params), "g.yaml", REGISTRY)
    except CheckFailed as exc:
        return [d.message for d in exc.diagnostics if "param" in d.message]
    return []


@pytest.mark.parametrize("type_name", TYPES)
def test_the_base_settings_pass_check_and_start(type_name: str) -> None:
    base = BASE.get(type_name, {})
    assert param_problems(type_name, base) == []
    with ModuleHarness(type_name, base, frames=_harness_frames()):
        pass  # entering starts the module, leaving stops it


#: Every declared parameter of every registered type.
FIELDS = [(t, name) for t in TYPES for name in REGISTRY.require(t).Params.model_fields]
#: Examples per parameter; fewer for a type whose start costs (SONY waits for its camera).
EXAMPLES = {"SONY": 3}


@pytest.mark.parametrize(("type_name", "name"), FIELDS)
def test_what_the_model_accepts_starts_and_what_it_refuses_check_refuses(
    type_name: str, name: str
) -> None:
    cls = REGISTRY.require(type_name)
    field = cls.Params.model_fields[name]
    base = BASE.get(type_name, {})
    seen = {"accepted": 0, "refused": 0}

    @settings(
        max_examples=EXAMPLES.get(type_name, 8),
        deadline=None,
        derandomize=True,
        database=None,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
    )
    @given(value=draws(field, keep=name in KEEP))
    def prove(value: object) -> None:
        params = {**base, name: value}
        try:
            cls.Params(**params)
        except pydantic.ValidationError:
            seen["refused"] += 1
            problems = param_problems(type_name, params)
            assert problems, f"check took {name}={value!r}, which the model refuses"
            return
        seen["accepted"] += 1
        # entering starts the module (and raises, failing the test, if start judges the value
        # again); leaving stops it and gives back what it held (a page server, a device)
        with ModuleHarness(cls, params, frames=_harness_frames()):
            pass

    prove()
    assert seen["accepted"] + seen["refused"] > 0
