"""What the console says of freshness: link ages from the producer's stamp (not the arrival),
the age of the data behind REG_VEL's command, the clocks, and a banner only for a real hold."""

from __future__ import annotations

import math

import numpy as np
import pytest

from umbra.connectors.messages import Image
from umbra.connectors.states import GuardReason, GuardStage, GuardState
from umbra.modules.operator.console import OperatorConsole
from umbra.modules.operator.console_view import BANNER_HOLD_S
from umbra.runtime.harness import ModuleHarness


def _image(stamp: float, origin: float) -> Image:
    return Image(pixels=np.zeros((4, 4, 3), np.uint8), stamp=stamp, origin=origin)


def test_a_link_is_as_old_as_its_producer_stamped_it_not_as_it_arrived() -> None:
    """A frame stamped 2 s ago that arrives now (a vision side fallen behind) reads 2 s old; an
    arrival age would read 0 ms and call it fresh."""
    with ModuleHarness(OperatorConsole, {"serve": False}) as h:
        h.step(10.0)
        h.push("image", _image(stamp=8.0, origin=7.9))
        h.step(0.01)
        h.module.view.track_links(h.now)
        (image,) = [row for row in h.module.view.state(h.now)["links"] if row["name"] == "image"]
        assert image["age_ms"] == pytest.approx(2010.0, abs=1.0)
        assert image["origin_ms"] == pytest.approx(2110.0, abs=1.0)
        h.push("image", _image(stamp=h.now, origin=h.now))
        h.step(0.01)
        h.module.view.track_links(h.now)  # the old one was shown until this one replaced it
        (image,) = [row for row in h.module.view.state(h.now)["links"] if row["name"] == "image"]
        assert image["age_ms"] == pytest.approx(2010.0, abs=1.0)  # its age when replaced
        h.step(0.05)
        h.module.view.track_links(h.now)
        (image,) = [row for row in h.module.view.state(h.now)["links"] if row["name"] == "image"]
        assert image["age_ms"] == pytest.approx(60.0, abs=1.0)  # then the new one's own age


def test_the_command_age_and_the_clocks_come_from_the_guard_and_the_links() -> None:
    with ModuleHarness(OperatorConsole, {"serve": False}) as h:
        h.push("image", _image(stamp=0.001, origin=0.001))
        h.push(
            "guard",
            GuardState(
                stage=GuardStage.ZERO,
                code=GuardReason.STALE_DATA,
                reason="command made from sensor data 1.30 s old (limit 0.25 s)",
                age_s=0.01,
                origin_age_s=1.3,
                stale=True,
            ),
        )
        h.step(0.01)
        ages = h.module.view.state(h.now)["data_age"]
        assert ages["command_origin_ms"] == pytest.approx(1300.0)
        assert ages["command_stale"] is True
        assert ages["clocks_synced"] is True and ages["clock_error_ms"] == 0.0  # one process
        h.module.image.clock_error = math.inf  # a link whose producer's clock is not measured
        assert h.module.view.state(h.now)["data_age"]["clocks_synced"] is False
        assert h.module.view.state(h.now)["data_age"]["clock_problem"] == ""
        why = "no clock reply from process `umbra` (session 1f) within 0.5 s"
        h.module.image.clock_problem = why  # as the runtime sets it: the page says why
        assert h.module.view.state(h.now)["data_age"]["clock_problem"] == why


def test_the_banner_shows_a_late_command_only_once_it_holds_the_arm() -> None:
    late = GuardState(
        stage=GuardStage.ZERO,
        code=GuardReason.WATCHDOG,
        reason="no new command for 0.105 s (link watchdog 0.100 s)",
    )
    old = GuardState(
        stage=GuardStage.ZERO,
        code=GuardReason.STALE_DATA,
        reason="command made from sensor data 0.40 s old (limit 0.25 s)",
        stale=True,
    )
    passing = GuardState(stage=GuardStage.PASSING, code=GuardReason.PASSING)
    with ModuleHarness(OperatorConsole, {"serve": False}) as h:
        view = h.module.view
        assert view.held_banner(1.0, None, late) == ""  # a blip: counted, not flashed
        assert view.held_banner(1.0 + BANNER_HOLD_S / 2, None, late) == ""
        assert "no new command" in view.held_banner(1.0 + BANNER_HOLD_S + 1e-6, None, late)
        assert view.held_banner(2.0, None, passing) == ""
        assert "0.40 s old" in view.held_banner(2.01, None, old)  # old data: at once
