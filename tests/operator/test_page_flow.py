"""A page is sent at most two frames and two states it has not said it showed, the newest of
each (never a queue a starved browser falls seconds behind on); the run's last state is known to
be shown before the console's process ends, and the socket is then closed cleanly (real console,
real websocket)."""

from __future__ import annotations

import json
import threading
from typing import Any

import pytest
from websockets.exceptions import ConnectionClosed

from tests.operator.helpers import Page, image
from tests.operator.test_console_module import _harness, _pump
from tests.poll import wait_for
from umbra.connectors.limits import MAX_PAGE_IN_FLIGHT
from umbra.modules.operator.page_flow import InFlight, PageFlow


class Reader:
    """What one page's socket has brought so far: its states and how many frames."""

    def __init__(self, page: Page) -> None:
        self.page = page
        self.states: list[dict[str, Any]] = []
        self.frames = 0
        self.closed: ConnectionClosed | None = None

    def read(self) -> None:
        """Take everything that has arrived (never waits)."""
        while self.closed is None:
            try:
                msg = self.page.ws.recv(timeout=0)
            except TimeoutError:
                return
            except ConnectionClosed as exc:
                self.closed = exc
                return
            if isinstance(msg, bytes):
                self.frames += 1
            elif json.loads(msg).get("type") == "state":
                self.states.append(json.loads(msg))

    def seen(self) -> int:
        """Say the newest state was drawn; its version."""
        version = int(self.states[-1]["version"])
        self.page.send("seen", state=version)
        return version


def test_in_flight_counts_by_version_and_never_expires_once_acknowledged() -> None:
    states = InFlight(paced=False)
    assert all(states.can_send() for _ in range(5))  # a client that never said: not held back
    states.sent(1)
    states.sent(2)
    states.acknowledge(1)
    assert states.versions == [2] and states.shown(1) and not states.shown(2)
    states.sent(3)
    assert not states.can_send()  # two on their way
    states.acknowledge(3)  # the newest shown: every one before it too
    assert states.versions == [] and states.can_send()
    frames = InFlight(paced=True)
    frames.sent(7)
    frames.sent(8)
    assert not frames.can_send()
    frames.deadline = 0.0  # a client that never acknowledged: one more after PAGE_ACK_TIMEOUT_S
    assert frames.can_send() and frames.versions == []
    frames.sent(9)
    frames.acknowledge()
    frames.sent(10)
    frames.sent(11)
    frames.deadline = 0.0  # once it has acknowledged, nothing expires
    assert not frames.can_send() and frames.versions == [10, 11]
    flow = PageFlow()
    flow.states.sent(4)
    assert flow.final_done(4) and not flow.final_done(5)  # a client that does not say: sent
    flow.states.acknowledge(3)
    assert not flow.final_done(4)  # a page that says: shown


def test_a_page_that_acknowledges_gets_two_states_and_frames_ahead_and_then_the_newest() -> None:
    with _harness() as h:
        acker, legacy = Reader(Page(h.module.url)), Reader(Page(h.module.url))
        try:
            _pump(h, lambda: (acker.read(), legacy.read(), acker.states and acker.frames)[-1])
            acker.seen()
            acker.page.send("painted", frame=0, latency_ms=1.0)
            before = len(acker.states), acker.frames
            # the page that never acknowledges is the clock: twenty states and two frame
            # timeouts (PAGE_ACK_TIMEOUT_S each) later, the other still has only two of each ahead
            states0, frames0 = len(legacy.states), legacy.frames
            _pump(
                h,
                lambda: (
                    (acker.read(), legacy.read())
                    and len(legacy.states) >= states0 + 20
                    and legacy.frames >= frames0 + 2
                ),
                timeout=20.0,
            )
            acker.read()
            assert len(acker.states) - before[0] == MAX_PAGE_IN_FLIGHT, (
                len(acker.states) - before[0]
            )
            assert acker.frames - before[1] <= MAX_PAGE_IN_FLIGHT  # (one may have been on its way)
            held = acker.seen()  # the newest one drawn: the next is the newest there is
            _pump(h, lambda: (acker.read(), len(acker.states) > before[0] + MAX_PAGE_IN_FLIGHT)[-1])
            assert acker.states[-1]["version"] > held + 1  # the ones between were never sent
        finally:
            acker.page.close()
            legacy.page.close()


def test_the_runs_end_is_shown_then_the_socket_closes_cleanly() -> None:
    h = _harness().__enter__()
    page = Reader(Page(h.module.url))
    ended = threading.Event()
    try:
        _pump(h, lambda: (page.read(), page.states)[-1])
        page.seen()
        stopping = threading.Thread(
            target=lambda: (h.__exit__(None, None, None), ended.set()), daemon=True
        )
        stopping.start()  # the module's stop waits for the page to show the end
        wait_for(
            lambda: (page.read(), page.states and page.states[-1]["phase"] == "ended")[-1],
            10.0,
            "the run's end on the page",
        )
        page.seen()
        wait_for(lambda: (page.read(), page.closed)[-1], 10.0, "the socket closed")
        assert page.closed is not None and page.closed.rcvd is not None
        assert (page.closed.rcvd.code, page.closed.rcvd.reason) == (1000, "run ended")
        assert ended.wait(10.0)
    finally:
        page.page.close()
        if not ended.is_set():
            ended.wait(10.0)


@pytest.mark.parametrize("field", [-1, 1.5, "7", None])
def test_a_seen_that_is_not_a_version_is_refused(field: object) -> None:
    with _harness() as h:
        page = Page(h.module.url)
        try:
            h.push("image", image())
            page.send("seen", state=field)
            notice = page.recv_text("notice")
            assert "state" in notice["text"] and "non-negative integer" in notice["text"]
        finally:
            page.close()
