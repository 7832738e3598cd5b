"""The simulated operator clicks when nobody acts, and steps aside once a person took control."""

from __future__ import annotations

from tests.operator.helpers import rectangle_contour
from umbra.connectors.states import Presence
from umbra.modules.world.operator_sim import OperatorSim
from umbra.runtime.harness import ModuleHarness


def test_the_simulated_operator_clicks_only_while_no_person_acted() -> None:
    with ModuleHarness(OperatorSim, {"click_delay_s": 0.1, "click_noise_px": 0.0}) as h:
        h.push("console", Presence(viewers=1))
        for _ in range(8):
            h.push("truth", rectangle_contour())
            h.step(dt=0.02)
        click = h.output("seed").uv
        assert abs(click[0] - 340.0) < 5 and abs(click[1] - 230.0) < 5
        assert h.module.summary()["stepped_aside_at_s"] is None
        h.push("console", Presence(person=True, acted=True, viewers=1, holder="ann"))
        h.step(dt=0.02)  # a person takes over after the click: noted in the summary
        assert h.module.summary()["stepped_aside_at_s"] is not None
        assert len(h.outputs("seed")) == 1
    with ModuleHarness(OperatorSim, {"click_delay_s": 0.1}) as h:
        h.push("console", Presence(person=True, acted=True, viewers=1, holder="ann"))
        for _ in range(20):
            h.push("truth", rectangle_contour())
            h.step(dt=0.02)
        assert not h.outputs("seed")
        assert h.module.summary()["stepped_aside_at_s"] is not None
