"""Parameters cannot disarm safety: floats are finite, safety parameters bounded with units,
every module's rate bounded, a watchdog ticks at least twice per timeout, `umbra describe`
shows the bounds, `check` refuses first what `run` would, a loop of modules needs a guard on it,
and a run that reaches its duration without a grasp fails."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pydantic
import pytest

from umbra.connectors.errors import CheckFailed
from umbra.connectors.limits import MAX_RATE_HZ
from umbra.connectors.params import Parameters, RunFile, param
from umbra.modules.arm.dh import puma560
from umbra.modules.arm.jacobian import jacobian_and_pose
from umbra.runtime.cli.cmd_describe import describe
from umbra.runtime.cli.main import main
from umbra.runtime.graph.check import check_text
from umbra.runtime.registry import Registry

CORPUS = Path(__file__).parent / "corpus"
ARM_GRAPH = (CORPUS / "graphs" / "set_base.yaml").read_text()


def _hostile_value(annotation: Any, default: Any, bad: float) -> Any | None:
    """``bad`` shaped as a value of ``annotation`` (a float, a list or a dict of floats)."""
    text = repr(annotation)
    if annotation is float or text in ("float | None", "typing.Optional[float]"):
        return bad
    if "list[float]" in text:
        return [bad] * max(1, len(default or []))
    if "dict[str, float]" in text:
        return {"k": bad}
    return None


def _float_fields() -> list[tuple[str, str, Any]]:
    registry, out = Registry(), []
    for name in registry.names():
        params_cls = registry.get(name).Params
        for field_name, field in params_cls.model_fields.items():
            default = field.get_default(call_default_factory=True)
            if _hostile_value(field.annotation, default, math.inf) is not None:
                out.append((name, field_name, default))
    return out


FLOAT_FIELDS = _float_fields()


def test_there_are_float_parameters_to_check() -> None:
    assert len(FLOAT_FIELDS) > 100


@pytest.mark.parametrize("bad", [math.inf, -math.inf, math.nan, "1e999", "Infinity", "-inf"])
def test_every_float_parameter_of_every_module_is_finite(bad: Any) -> None:
    registry, accepted = Registry(), []
    for type_name, field_name, default in FLOAT_FIELDS:
        params_cls = registry.get(type_name).Params
        field = params_cls.model_fields[field_name]
        value = _hostile_value(field.annotation, default, bad)
        try:
            params_cls(**{field_name: value})
        except pydantic.ValidationError as exc:
            kinds = {e["type"] for e in exc.errors() if e["loc"] and e["loc"][0] == field_name}
            if "finite_number" not in kinds:
                accepted.append(f"{type_name}.{field_name}: {kinds}")
        else:
            accepted.append(f"{type_name}.{field_name} accepted {value!r}")
    assert not accepted, "\n".join(accepted)


def test_no_number_parameter_of_any_module_takes_a_boolean() -> None:
    registry, accepted = Registry(), []
    for type_name, field_name, default in FLOAT_FIELDS:
        params_cls = registry.get(type_name).Params
        field = params_cls.model_fields[field_name]
        value = _hostile_value(field.annotation, default, True)  # type: ignore[arg-type]
        try:
            params_cls(**{field_name: value})
        except pydantic.ValidationError as exc:
            if "found a boolean" not in str(exc):
                accepted.append(f"{type_name}.{field_name}: {exc}")
        else:
            accepted.append(f"{type_name}.{field_name} accepted {value!r}")
    assert not accepted, "\n".join(accepted)


def test_a_boolean_for_a_number_is_refused_at_its_line(capsys) -> None:
    text = ARM_GRAPH.replace("params: {timeout: 0.1}", "params: {timeout: true}")
    (problem,) = _problems(text)
    assert problem == (
        "g.yaml:6:53: error: parameter `timeout` of `reg`: "
        "expected a number, found a boolean (true/false)"
    )
    graph = CORPUS / "graphs" / "set_base.yaml"
    argv = ["run", str(graph), "--clock", "sim", "--duration", "0.1", "--quiet"]
    assert main([*argv, "--set", "reg.max_linear=yes"]) == 2
    assert "`max_linear` of `reg`: expected a number, found a boolean" in capsys.readouterr().err
    assert main([*argv, "--set", "jnts.initial_q_deg=[0, 90, -90, 0, 0, false]"]) == 2
    assert "found a boolean" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("path", "ok"),
    [
        ("plot.png", True),
        ("plots/errors.png", True),
        ("", True),  # no file
        ("../plot.png", False),
        ("plots/../../plot.png", False),
        ("/tmp/plot.png", False),
        ("C:\\plot.png", False),
        ("..\\..\\plot.png", False),
    ],
)
def test_a_file_a_module_writes_stays_in_the_run_folder(path: str, ok: bool) -> None:
    class Writes(Parameters):
        path: RunFile = param("plot.png", "output file")

    if ok:
        assert Writes(path=path).path == path
    else:
        with pytest.raises(pydantic.ValidationError, match="run folder"):
            Writes(path=path)


@pytest.mark.parametrize(
    ("type_name", "field", "accepted", "rejected"),
    [
        ("REG_VEL", "timeout", [1e-3, 1.0], [0.0, 1.0001, 5.0]),
        ("REG_VEL", "max_linear", [0.0, 1.0], [-0.1, 1.01, 1e9]),
        ("REG_VEL", "max_angular", [0.0, math.pi], [-0.1, 3.2, 100.0]),
        ("WOLVERINE_JNTS", "max_command_age", [0.01, 1.0], [0.0, 1.5, 10.0]),
        ("WOLVERINE_JNTS", "accel_max", [8.0, 1000.0], [0.0, 1e6]),
        ("WOLVERINE_KIN", "max_state_age", [0.1, 1.0], [0.0, 2.0]),
        ("vsServo", "max_linear", [0.05, 1.0], [0.0, 2.0]),
        ("vsServo", "max_angular", [0.3, math.pi], [0.0, 4.0]),
        ("WOLVERINE_KIN", "tool_xyz", [[0, 0, 0.14]], [[0, 0], [0, 0, 0, 0]]),
        ("WOLVERINE_JNTS", "initial_q_deg", [[0, 90, -90, 0, 0, 0]], [[0, 0, 0], [0] * 7]),
    ],
)
def test_safety_parameters_are_bounded(
    type_name: str, field: str, accepted: list[Any], rejected: list[Any]
) -> None:
    params_cls = Registry().get(type_name).Params
    for value in accepted:
        assert getattr(params_cls(**{field: value}), field) == value
    for value in rejected:
        with pytest.raises(pydantic.ValidationError):
            params_cls(**{field: value})


def test_describe_shows_bounds_with_units() -> None:
    text = describe(Registry().get("REG_VEL"))
    assert "timeout: float = 0.2 [s], in (0, 1]" in text
    assert "max_linear: float = 0.1 [m/s], in [0, 1]" in text
    assert "max_angular: float = 0.5 [rad/s], in [0, 3.14159]" in text
    assert "tool_xyz: list[float] = [0.0, 0.0, 0.0] [m], length 3" in describe(
        Registry().get("WOLVERINE_KIN")
    )


def _problems(text: str) -> list[str]:
    with pytest.raises(CheckFailed) as info:
        check_text(text, "g.yaml")
    return [str(d) for d in info.value.diagnostics]


@pytest.mark.parametrize(("rate", "ok"), [(20, True), (19.9, False), (1, False)])
def test_a_watchdog_ticks_at_least_twice_per_timeout(rate: float, ok: bool) -> None:
    text = ARM_GRAPH.replace(
        "reg: {type: REG_VEL, rate: 100", f"reg: {{type: REG_VEL, rate: {rate}"
    )
    if ok:
        assert check_text(text, "g.yaml").modules["reg"].spec.rate == rate
    else:
        (problem,) = _problems(text)
        assert problem.startswith("g.yaml:6:30: error: module `reg` (REG_VEL): rate")
        assert "must tick at least twice per timeout (20 Hz)" in problem


@pytest.mark.parametrize(
    ("rate", "ok"), [(MAX_RATE_HZ, True), (1e-3, True), (10_001, False), (1e-4, False)]
)
def test_every_module_rate_is_bounded(rate: float, ok: bool) -> None:
    text = ARM_GRAPH.replace(
        "vision: {type: TwistSource, rate: 100", f"vision: {{type: TwistSource, rate: {rate!r}"
    )
    if ok and rate >= 4:
        check_text(text, "g.yaml")
    elif ok:  # a legal rate, but a command source that slow makes commands older than REG_VEL's
        (problem,) = _problems(text)  # bound: that is what check says, not the rate's limits
        assert "accepts commands made from sensor data up to 0.25 s old" in problem
    else:
        (problem,) = _problems(text)
        assert problem.startswith("g.yaml:5:37: error: rate of module `vision` must be from 0.001")


GUARDED_LOOP = """graph: guarded_loop
frames:
  tool->camera: {xyz: [0.0, 0.06, 0.04], rpy_deg: [0, 0, 90]}
modules:
  reg: {type: REG_VEL, rate: 100, params: {timeout: 0.1}}
  rot: {type: ROTATE_KIN}
  back: {type: ROTATE_KIN, params: {camera_frame: tool, tool_frame: camera, mount_xyz: [0, 0, 0],
         mount_rpy_deg: [0, 0, 0]}}
  kin: {type: WOLVERINE_KIN}
  jnts: {type: WOLVERINE_JNTS, rate: 100}
connections:
  - reg.twist -> rot.camera_twist
  - rot.tool_twist -> back.camera_twist
  - back.tool_twist ~> reg.command
  - rot.tool_twist -> kin.tool_twist
  - kin.joint_rates -> jnts.rates
  - jnts.joint_state ~> kin.joint_state
"""


def test_a_loop_with_a_guard_on_it_is_guarded() -> None:
    """The guard rule accepts the loop; what is left is that a command fed back into its own
    guard is dated by itself, so its origin could never advance: check says so."""
    (problem,) = _problems(GUARDED_LOOP)
    assert "origins flow around the loop back -> reg -> rot -> back" in problem
    assert "must be fed through a safety guard" not in problem


def test_a_loop_without_a_guard_is_unguarded() -> None:
    text = GUARDED_LOOP.replace("  - back.tool_twist ~> reg.command\n", "").replace(
        "reg.twist -> rot.camera_twist", "back.tool_twist ~> rot.camera_twist"
    )
    text = text.replace("  reg: {type: REG_VEL, rate: 100, params: {timeout: 0.1}}\n", "")
    (problem,) = _problems(text)
    assert problem.startswith("g.yaml:14:5: error: `jnts.rates` must be fed through a safety guard")
    assert "rot -> back -> rot -> kin -> jnts.rates" in problem


def test_negative_numbers_are_values_on_the_command_line(capsys) -> None:
    q = [-0.5, 0.2, -0.1, 0.0, 0.3, -2.0]
    assert main(["arm", "--q", ",".join(f"{v:g}" for v in q), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    _, T_base_flange = jacobian_and_pose(puma560(), np.array(q))
    np.testing.assert_allclose(out["T_base_flange"], T_base_flange, atol=1e-12)


OUTCOME = """graph: outcome
frames:
  base->table: {xyz: [0, 0, 0.25]}
  flange->tool: {xyz: [0, 0, 0.14]}
  tool->camera: {xyz: [0, 0, -0.12]}
modules:
  vision: {type: TwistSource, rate: 100, params: {twist: [0, 0, 0, 0, 0, 0]}}
  reg: {type: REG_VEL, rate: 100, params: {timeout: 0.1}}
  rot: {type: ROTATE_KIN}
  kin: {type: WOLVERINE_KIN, params: {tool_xyz: [0, 0, 0.14]}}
  jnts: {type: WOLVERINE_JNTS, rate: 100,
         params: {initial_q_deg: [14.482, 45.603, -182.743, 0.0, -42.86, -165.518]}}
  world: {type: World, rate: 100}
connections:
  - vision.twist -> reg.command
  - reg.twist -> rot.camera_twist
  - rot.tool_twist -> kin.tool_twist
  - kin.joint_rates -> jnts.rates
  - jnts.joint_state ~> kin.joint_state
  - jnts.true_joint_state ~> world.joint_state
"""


@pytest.mark.parametrize(("end_run", "status"), [("true", 1), ("false", 0)])
def test_a_run_that_reaches_its_duration_without_a_grasp_fails(
    end_run: str, status: int, tmp_path: Path
) -> None:
    graph = tmp_path / "outcome.yaml"
    graph.write_text(OUTCOME)
    out = tmp_path / "run"
    argv = ["run", str(graph), "--clock", "sim", "--duration", "0.3", "--out", str(out)]
    assert main([*argv, "--quiet", "--set", f"world.end_run={end_run}"]) == status
    summary = json.loads((out / "summary.json").read_text())
    assert summary["exit_code"] == status
    assert summary["clock_time_s"] == pytest.approx(0.3, abs=0.011)
    if status:
        assert summary["reason"] == (
            "duration 0.3 s reached; world: no grasp before the run's duration ended"
        )
    else:
        assert summary["reason"] == "duration 0.3 s reached"
