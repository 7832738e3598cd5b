"""Only a clock's owner answers for it, and the error bound is never dropped.

Real zenoh sessions on loopback, no access rules (as with ``--insecure``: the weakest setup, where
only the clock exchange's own checks stand): a third session declares a queryable on the
producer's clock key and holds every query until zenoh's timeout, or answers with a lie claiming
to read the consumer's own clock. Neither widens the bound nor moves the offset: replies are
taken as they come and only from the producer's session.
"""

from __future__ import annotations

import json
import math
import threading
import time
from collections.abc import Iterator

import msgspec
import pytest
import zenoh

from tests.poll import wait_for
from umbra.connectors.messages import Scalar
from umbra.runtime.links.clock_identity import clock_identity
from umbra.runtime.links.clock_sync import (
    QUERY_TIMEOUT_S,
    ClockReply,
    ClockSync,
    Offset,
    clock_key,
    translated,
)
from umbra.runtime.links.config import free_loopback_ports
from umbra.runtime.links.session import wait_joined

PREFIX = "umbra/clocktest"


def _open(listen: list[str], connect: list[str]) -> zenoh.Session:
    off = {"multicast": {"enabled": False}, "gossip": {"enabled": False}}
    config = {
        "mode": "peer",
        "scouting": off,
        "listen": {"endpoints": listen},
        "connect": {"endpoints": connect},
    }
    return zenoh.open(zenoh.Config.from_json5(json.dumps(config)))


@pytest.fixture
def sessions() -> Iterator[tuple[zenoh.Session, zenoh.Session, zenoh.Session]]:
    """Producer, consumer and an impostor, all connected to one another."""
    ports = free_loopback_ports(3)
    eps = [f"tcp/127.0.0.1:{p}" for p in ports]
    opened = [_open([eps[0]], []), _open([eps[1]], [eps[0]]), _open([eps[2]], eps[:2])]
    try:
        for s in opened:
            assert wait_joined(s, 2, 10.0) >= 2
        yield opened[0], opened[1], opened[2]
    finally:
        for s in opened:
            s.close()


def _sync(
    session: zenoh.Session, process: str, producer: zenoh.Session | None, identity: str
) -> ClockSync:
    producers = {"umbra"} if producer is not None else set()
    zid = str(producer.zid()) if producer is not None else None
    return ClockSync(session, PREFIX, process, producers, lambda _p: zid, identity=identity)


def _measured(consumer: ClockSync, producer: str = "umbra") -> Offset:
    return wait_for(
        lambda: consumer.exchange(producer),
        10.0,
        lambda: f"an offset measured: {consumer.problem(producer)}",
        0,
    )


def test_a_producer_on_our_very_clock_is_dated_with_no_error(sessions) -> None:  # type: ignore[no-untyped-def]
    producer_s, consumer_s, _ = sessions
    ours = clock_identity()
    assert ours, "this kernel names its boot and time namespace"
    producer = _sync(producer_s, "umbra", None, ours)
    consumer = _sync(consumer_s, "smart", producer_s, ours)
    try:
        found = _measured(consumer)
        assert found.same_clock and found.offset == 0.0 and found.error == 0.0
        sample = Scalar(value=1.0, stamp=10.0, origin=9.0)
        assert translated(sample, found) is sample  # nothing to translate
    finally:
        consumer.close()
        producer.close()


def test_another_clock_is_measured_and_its_bound_always_applied(sessions) -> None:  # type: ignore[no-untyped-def]
    producer_s, consumer_s, _ = sessions
    producer = _sync(producer_s, "umbra", None, "another-boot/time:[1]")
    consumer = _sync(consumer_s, "smart", producer_s, clock_identity())
    try:
        found = _measured(consumer)
        # the same monotonic clock in truth, but nothing proves it: measured, never "same"
        assert not found.same_clock
        assert 0.0 < found.error < QUERY_TIMEOUT_S / 2
        assert abs(found.offset) <= found.error  # the offset looks like nothing...
        moved = translated(Scalar(value=1.0, stamp=10.0, origin=9.0), found)
        # ...and the origin is still moved back by the whole bound (data only ever looks older)
        assert moved.origin == pytest.approx(9.0 - found.offset - found.error, abs=1e-12)
        assert moved.origin < 9.0 + 1e-12 - (found.offset + found.error) + 1e-9
    finally:
        consumer.close()
        producer.close()


@pytest.mark.parametrize("impostor_kind", ["withholds", "lies"])
def test_an_impostor_on_the_clock_key_neither_widens_the_bound_nor_moves_the_offset(
    sessions,  # type: ignore[no-untyped-def]
    impostor_kind: str,
) -> None:
    producer_s, consumer_s, impostor_s = sessions
    consumer_identity = clock_identity()
    producer = _sync(producer_s, "umbra", None, "producer-host/time:[7]")
    consumer = _sync(consumer_s, "smart", producer_s, consumer_identity)
    held: list[zenoh.Query] = []
    asked = threading.Event()

    def impostor(query: zenoh.Query) -> None:
        asked.set()
        if impostor_kind == "withholds":
            held.append(query)  # never answered: zenoh waits for it until the query's timeout
            return
        lie = ClockReply(time.monotonic() - 0.3, consumer_identity)  # "I read your clock"
        query.reply(query.key_expr, msgspec.msgpack.encode(lie))

    key = clock_key(PREFIX, "umbra", str(producer_s.zid()))
    queryable = impostor_s.declare_queryable(key, impostor)
    try:
        # until the impostor's declaration has reached the consumer
        wait_for(
            asked.is_set,
            10.0,
            "the impostor to be asked",
            0,
            step=lambda: consumer.exchange("umbra"),
        )
        for _ in range(3):  # exchanges the impostor was asked in
            found = _measured(consumer)
        assert not found.same_clock  # the lie about our clock was not taken
        # the true reply came at once: the bound is the loopback round trip, not the 0.5 s the
        # impostor held the query for
        assert found.error < QUERY_TIMEOUT_S / 5, found
        assert abs(found.offset) <= found.error + 1e-3  # one host's clock in truth
    finally:
        queryable.undeclare()
        held.clear()
        consumer.close()
        producer.close()


def test_a_producer_that_cannot_be_dated_is_said_why(sessions) -> None:  # type: ignore[no-untyped-def]
    producer_s, consumer_s, _ = sessions
    # the producer's session is known, but its clock is never declared (no ClockSync there)
    consumer = _sync(consumer_s, "smart", producer_s, clock_identity())
    try:
        assert consumer.exchange("umbra") is None
        why = consumer.problem("umbra")
        assert f"no clock reply from process `umbra` (session {producer_s.zid()})" in why
        assert "0.5 s" in why
        assert consumer.summary()["umbra"] == {"measured": False, "undatable_why": why}
        assert math.isinf(consumer.offsets.get("umbra", Offset(0, math.inf, 0, 0)).error)
    finally:
        consumer.close()
