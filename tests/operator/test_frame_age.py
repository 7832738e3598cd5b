"""The age of the picture the page shows, on the console's side: one bound (``stale_page_s``)
sent to the page, and one origin (the camera's capture) for the age the page shows and the age
the console refuses an action with."""

from __future__ import annotations

import msgspec
import pytest

from tests.operator.helpers import image
from tests.operator.test_console_module import _harness, _operator, _pump
from umbra.modules.operator.console_view import FRAME_AGE_WARN_FRACTION


def test_the_page_gets_the_consoles_own_bound_and_where_it_turns_amber() -> None:
    with _harness(serve=False, stale_page_s=0.8) as h:
        h.push("image", image())
        h.step(dt=0.01)
        bounds = h.module.view.state(h.now)["frame_age"]
    assert bounds == {"limit_ms": 800.0, "warn_ms": 800.0 * FRAME_AGE_WARN_FRACTION}
    assert 0 < bounds["warn_ms"] < bounds["limit_ms"]


def test_an_action_is_refused_by_the_age_since_capture_the_page_is_told() -> None:
    """A picture captured 0.7 s before it reached the console (a slow link) is 0.7 s old for
    the page (its header's ``age_ms``, from which the page dates what it shows) and for the
    refusal of a click made on it, however fresh its arrival."""
    with _harness(stale_page_s=0.5) as h:
        page = _operator(h)
        try:
            old = msgspec.structs.replace(image(), stamp=h.now - 0.7, origin=h.now - 0.7)
            seq = h.push("image", old).seq
            h.step(dt=0.001)
            frame = h.module._app.frames.get()[1]
            assert frame.seq == seq
            assert frame.age_at_handoff == pytest.approx(0.701, abs=1e-6)
            page.send("click", u=340.0, v=230.0, frame=seq)
            _pump(h, lambda: h.module.counts["refused"] == 1)
            text = next(n.text for n in h.module.board.lines if n.level == "error")
            age = float(text.split(" is ")[1].split(" s old")[0])
            assert 0.7 < age < 0.7 + 5.0, text  # its capture, not its arrival (0.001 s)
            assert text.endswith("expected at most 0.500 s")
            assert h.module.counts["seeds"] == 0
            seq = h.push("image", image()).seq  # captured now: passed on
            h.step(dt=0.001)
            page.send("click", u=340.0, v=230.0, frame=seq)
            _pump(h, lambda: h.module.counts["seeds"] == 1)
        finally:
            page.close()
