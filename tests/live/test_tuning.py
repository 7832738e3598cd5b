"""Tunable parameters changed while a graph runs: declared, never safety ones, validated as
``--set`` is, applied between two steps, logged and recorded."""

from __future__ import annotations

import json
import logging
from pathlib import Path

import pytest
from mcap.reader import make_reader

from tests.live.graphs import small_plan
from umbra.connectors.messages import Message
from umbra.connectors.module import Module
from umbra.connectors.params import Parameters, param
from umbra.runtime.live.parameters import ParameterTable
from umbra.runtime.registry import Registry
from umbra.runtime.scheduler import Scheduler, SchedulerOptions
from umbra.runtime.tuning import CHANGES_TOPIC, tunable_problem


def test_a_safety_parameter_cannot_be_declared_tunable() -> None:
    with pytest.raises(TypeError, match="safety and tunable"):

        class _Params(Parameters):
            speed: float = param(0.1, "a clamp", unit="m/s", safety=True, tunable=True)

    with pytest.raises(TypeError, match="safety guard"):

        class _Guard(Module):
            SAFETY_GUARD = True

            class Params(Parameters):
                timeout: float = param(0.1, "watchdog", unit="s", tunable=True)


def test_no_registered_module_offers_a_safety_parameter_for_tuning() -> None:
    registry = Registry()
    tunable = {}
    for name in registry.names():
        cls = registry.get(name)
        assert cls is not None
        ok = [p for p in cls.Params.model_fields if not tunable_problem(cls, "m", p)]
        if ok:
            tunable[name] = ok
    # a few genuinely tunable parameters; none of a guard, none marked safety
    assert "REG_VEL" not in tunable and "WOLVERINE_JNTS" not in tunable
    assert tunable["Gain"] == ["gain", "bias"]
    assert "tension" in tunable["vsSnake"] and "gains" in tunable["vsServo"]
    assert "max_linear" not in tunable["vsServo"]


def _run_with_change(tmp_path: Path, request: tuple[str, str, object], at: float) -> Scheduler:
    """The small graph on the sim clock for 1 s, recording; ``request`` is made *during* the
    tick at ``at`` s (while `src` steps, before `servo` does)."""
    plan = small_plan()
    plan.spec.record.enabled = True
    sched = Scheduler(plan, SchedulerOptions(clock="sim", duration=1.0, output_dir=tmp_path))
    seen: list[tuple[float, float]] = []
    sched.servo_seen = seen  # type: ignore[attr-defined]
    asked: list[str] = []

    def during_src_step(sample: Message, now: float) -> None:
        if now >= at and not asked:
            asked.append(sched.tuner.request(*request, "test"))  # type: ignore[arg-type]

    sched.modules["src"].outputs["output"].sinks.append(during_src_step)
    sched.modules["servo"].outputs["output"].sinks.append(
        lambda s, now: seen.append((now, s.value))  # type: ignore[attr-defined]
    )
    sched.asked = asked  # type: ignore[attr-defined]
    sched.run()
    return sched


def test_a_change_is_applied_between_steps_logged_and_recorded(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.INFO)
    sched = _run_with_change(tmp_path, ("servo", "gain", 3.0), at=0.5)
    assert sched.asked == [""]  # type: ignore[attr-defined]
    seen = sched.servo_seen  # type: ignore[attr-defined]
    before = [v for t, v in seen if t < 0.5 - 1e-9]
    same_tick = [v for t, v in seen if abs(t - 0.5) < 1e-9]
    after = [v for t, v in seen if t > 0.5 + 1e-9]
    assert before and set(before) == {1.0}  # 0.5 * 2.0
    assert same_tick == [1.0]  # asked in the middle of this tick: not under servo's feet
    assert after and set(after) == {6.0}  # 3.0 * 2.0 from the next tick on
    assert sched.modules["servo"].params.gain == 3.0
    assert "param servo.gain 0.5 -> 3.0 by test" in caplog.text

    with open(tmp_path / "recording.mcap", "rb") as f:
        found = [
            (channel.topic, schema.name, json.loads(msg.data))
            for schema, channel, msg in make_reader(f).iter_messages(topics=[CHANGES_TOPIC])
        ]
    assert len(found) == 1
    _topic, schema_name, data = found[0]
    assert schema_name == "umbra.ParamChange"
    assert (data["module"], data["param"], data["old"], data["value"]) == (
        "servo",
        "gain",
        "0.5",
        "3.0",
    )


@pytest.mark.parametrize(
    ("name", "value", "why", "unchanged"),
    [
        ("guard.timeout", 0.5, "safety guard", 0.2),
        ("servo.gain", ".inf", "finite", 0.5),
        ("servo.gain", "fast", "valid number", 0.5),
        ("servo.gian", 1.0, "has no parameter `gian`", None),
        ("src.value", 1.0, "not declared tunable", 2.0),
        ("nobody.gain", 1.0, "expected MODULE.PARAM of a module of the graph", None),
    ],
)
def test_a_viewer_s_change_is_refused_with_the_reason(
    name: str, value: object, why: str, unchanged: float | None
) -> None:
    plan = small_plan()
    sched = Scheduler(plan, SchedulerOptions(clock="sim", duration=0.1))
    table = ParameterTable(plan)
    table.serve_locally(sched.tuner, list(sched.modules))
    answer, refusals = table.set("viewer #1", [(name, value)])
    assert len(refusals) == 1 and why in refusals[0], refusals
    # the viewer is answered with the value the parameter still has (none: no such parameter)
    assert answer == ([] if unchanged is None else [{"name": name, "value": unchanged}])
    assert not sched.tuner.pending


def test_a_viewer_s_change_is_taken_as_set_reads_it() -> None:
    plan = small_plan()
    sched = Scheduler(plan, SchedulerOptions(clock="sim", duration=0.1))
    table = ParameterTable(plan)
    table.serve_locally(sched.tuner, list(sched.modules))
    answer, refusals = table.set("viewer #1", [("servo.bias", "0.25")])  # text, as --set
    assert refusals == [] and answer == [{"name": "servo.bias", "value": 0.25}]
    assert table.get(["servo.bias"]) == [{"name": "servo.bias", "value": 0.25}]
    assert sched.tuner.pending
    sched.tuner.apply(0.0)
    assert sched.modules["servo"].params.bias == 0.25


def test_only_the_tuner_may_put_parameter_changes_and_each_process_reads_its_own() -> None:
    from umbra.runtime.links.acl import (
        TUNER_USER,
        by_username,
        local_observer,
        param_key,
        zenoh_acl,
    )

    plan = small_plan()
    acl = zenoh_acl(plan, by_username, [local_observer(plan)], by_username(TUNER_USER))
    rules = {r["id"]: r for r in acl["rules"]}
    changes = [param_key(plan.key_prefix, p) for p in plan.populated_processes]
    puts = [r for r in acl["rules"] if "put" in r["messages"] and r["flows"] == ["ingress"]]
    on_changes = [r["id"] for r in puts if set(r["key_exprs"]) & set(changes)]
    assert on_changes == ["tuner: parameter changes"]
    assert rules["tuner: parameter changes"]["key_exprs"] == sorted(changes)
    tuner = [p for p in acl["policies"] if p["subjects"] == ["tuner"]]
    assert len(tuner) == 1 and len(tuner[0]["rules"]) == 2  # put, and hear of subscribers
    assert zenoh_acl(plan, by_username, [local_observer(plan)]) == {
        **acl,
        "rules": [r for r in acl["rules"] if not r["id"].startswith("tuner")],
        "subjects": [s for s in acl["subjects"] if s["id"] != "tuner"],
        "policies": [p for p in acl["policies"] if p["subjects"] != ["tuner"]],
    }  # a run not served live has no tuner at all
