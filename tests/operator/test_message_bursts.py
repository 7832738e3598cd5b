"""A burst of messages is one line with its count: the console's Messages board keeps a refusal
said again with other numbers (a new age, another frame) on its line, while information about
different people and refusals of different kinds stay lines of their own."""

from __future__ import annotations

import pytest

from tests.operator.helpers import image
from tests.operator.test_console_module import _frame_seq, _harness, _operator, _pump, _state
from umbra.modules.operator.message_board import MessageBoard, same_line_key


def _stale(age_s: float) -> str:
    return f"stale page: the image you acted on is {age_s:.3f} s old, expected at most 0.500 s"


def test_thirty_stale_page_refusals_are_one_line_with_the_newest_age_and_x30() -> None:
    board = MessageBoard(size=30)
    board.post("viewer 1 (127.0.0.1) is watching", 0.5)
    for k in range(30):
        board.post(_stale(1.128 + 0.05 * k), 1.0 + 0.1 * k, to="page-a", level="error")
    lines = board.for_page()
    assert len(lines) == 2
    burst = lines[0]
    assert burst["count"] == 30 and burst["to"] == "page-a" and burst["level"] == "error"
    assert burst["text"] == _stale(1.128 + 0.05 * 29)  # the newest numbers: 2.578 s
    assert abs(burst["t"] - 3.9) < 1e-9 and burst["id"] == 31
    # the same refusal to another page, and another refusal, are lines of their own
    board.post(_stale(0.9), 4.0, to="page-b", level="error")
    board.post("refused click: take control first", 4.1, to="page-a", level="error")
    assert [(m["to"], m["count"]) for m in board.for_page()[:3]] == [
        ("page-a", 1),
        ("page-b", 1),
        ("page-a", 30),
    ]
    # information is a repeat only in the same words: two viewers are two lines
    board.post("viewer 2 (127.0.0.1) is watching", 5.0)
    watching = [m["text"] for m in board.for_page() if "is watching" in m["text"]]
    assert watching == ["viewer 2 (127.0.0.1) is watching", "viewer 1 (127.0.0.1) is watching"]


def test_an_errors_numbers_do_not_make_it_another_line_but_its_words_do() -> None:
    assert same_line_key("s", "error", "frame 12 is no longer live; 0.50 s") == same_line_key(
        "s", "error", "frame 4031 is no longer live; 1e-3 s"
    )
    assert same_line_key("s", "error", "frame 12 is no longer live") != same_line_key(
        "s", "error", "frame 12 is outside the image"
    )
    assert same_line_key("s", "info", "viewer 2 is watching") != same_line_key(
        "s", "info", "viewer 3 is watching"
    )


@pytest.mark.slow
@pytest.mark.untimed
def test_a_page_clicking_thirty_stale_frames_sees_one_line_counted_x30() -> None:
    """Over the real socket: the holder clicks a frame that grows older between its clicks;
    every click is refused with its own age, and the state the page gets has one line."""
    with _harness(stale_page_s=0.5) as h:
        page = _operator(h)
        try:
            old = _frame_seq(h)
            for _ in range(30):  # 0.6 s of run time: the frame is stale from now on
                h.push("image", image())
                h.step(dt=0.02)
            for k in range(30):
                page.send("click", u=340.0, v=230.0, frame=old)
                _pump(h, lambda k=k: h.module.counts["refused"] == k + 1)
            state = _state(
                h,
                page,
                lambda s: any(n["count"] == 30 for n in s["notices"] if n["level"] == "error"),
            )
            stale = [n for n in state["notices"] if "stale page" in n["text"]]
            assert len(stale) == 1 and stale[0]["to"] == page.session, stale
            assert stale[0]["text"].startswith("stale page: the image you acted on is 0.")
            ages = {m.text for m in h.module.board.lines}  # the newest age is the line's
            assert len([t for t in ages if "stale page" in t]) == 1
            assert h.module.counts["seeds"] == 0
        finally:
            page.close()
