"""Samples that come before their producer's clock is measured wait for it, in order, instead of
being undatable for good (a status sent once at start would otherwise taint every output made
from it)."""

from __future__ import annotations

import json
import math

import zenoh

from umbra.connectors.messages import Scalar
from umbra.runtime.links.clock_sync import HOLD_UNDATED_S, ClockReply, ClockSync


def _session() -> zenoh.Session:
    off = {"multicast": {"enabled": False}, "gossip": {"enabled": False}}
    return zenoh.open(zenoh.Config.from_json5(json.dumps({"scouting": off})))


def test_early_samples_wait_for_the_clock_then_go_in_order_dated() -> None:
    now = [100.0]
    session = _session()
    sync = ClockSync(session, "t", "smart", {"umbra"}, lambda p: None, clock=lambda: now[0])
    got: list[Scalar] = []
    try:
        sync.date("umbra", Scalar(value=1.0, stamp=50.0, origin=49.0), got.append)
        sync.date("umbra", Scalar(value=2.0, stamp=50.1, origin=49.1), got.append)
        assert got == [] and sync.held_undated == 2  # no clock yet: held, not undatable
        reply = ClockReply(105.0, "another-host/time:[1]")  # the producer is 5 s ahead of us
        sync._record("umbra", 100.0, reply, 100.0002)
        sync._release("umbra")
        assert [m.value for m in got] == [1.0, 2.0]  # in order
        # offset 4.9999 s (the reply in the middle of the 0.2 ms round trip), error 0.1 ms: the
        # stamp moved by the offset, the origin by the offset and the error (never younger)
        assert math.isclose(got[0].stamp, 45.0001) and math.isclose(got[0].origin, 44.0)
        sync.date("umbra", Scalar(value=3.0, stamp=50.2, origin=49.2), got.append)
        assert got[-1].value == 3.0 and math.isclose(got[-1].stamp, 45.2001)
    finally:
        sync.close()
        session.close()


def test_a_producer_whose_clock_never_answers_gets_its_samples_through_as_undatable() -> None:
    now = [10.0]
    session = _session()
    sync = ClockSync(session, "t", "smart", {"umbra"}, lambda p: None, clock=lambda: now[0])
    got: list[Scalar] = []
    try:
        sync.date("umbra", Scalar(value=1.0, stamp=5.0, origin=5.0), got.append)
        sync._release("umbra")
        assert got == []
        now[0] += HOLD_UNDATED_S
        sync.exchange("umbra")  # nobody to ask: no proven session of `umbra`
        sync._release("umbra")
        assert len(got) == 1 and got[0].origin == -math.inf  # old: every guard refuses it
        summary = sync.summary()
        assert summary["undatable"] == 1
        assert "no live session of process `umbra`" in summary["umbra"]["undatable_why"]
    finally:
        sync.close()
        session.close()
