"""Zenoh's matching status as the sign that a subscription has reached a publisher's session."""

from __future__ import annotations

import uuid

import zenoh

from tests.poll import wait_for


def wait_subscriptions_reached(
    subscriber: zenoh.Session, publisher: zenoh.Session, timeout_s: float, what: str
) -> None:
    """Wait until ``publisher`` knows every subscription that ``subscriber`` has declared so far
    (``what`` names them). A publisher's matching status says only whether anyone at all matches
    (a graph's own consumer may already), so this declares a probe subscription on a key of its
    own on ``subscriber``, after the others, and waits for a probe publisher on ``publisher`` to
    match it: a session's declarations reach a peer in the order it made them."""
    key = f"umbra-test/probe/{uuid.uuid4().hex}"
    probe = subscriber.declare_subscriber(key, lambda _sample: None)
    pub = publisher.declare_publisher(key)
    try:
        wait_for(lambda: pub.matching_status.matching, timeout_s, what)
    finally:
        pub.undeclare()
        probe.undeclare()
