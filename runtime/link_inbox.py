"""Link samples waiting for the next tick, and how a tick takes them in.

The transport appends ``(register, sample, in_order)`` on its threads; the tick writes them into
the registers. On an events link (``in_order``: operator actions, gripper, paths) one sample per
register per tick, in order: the rest wait for the next tick, which follows at once, so a
consumer sees every event as it would in one process. On a state link the newest sample wins and
the ones it replaced are counted (``Register.superseded``), so a starved consumer catches up at
once instead of working through a backlog of the past.
"""

from __future__ import annotations

from collections import deque
from typing import Any

from umbra.connectors.messages import Message
from umbra.connectors.ports import Register

Inbox = deque[tuple[Register[Any], Message, bool]]


def drain(inbound: Inbox, now: float) -> bool:
    """Write the samples of ``inbound`` that arrived before this call into their registers at
    ``now`` [s]; True when some wait for the next tick (events beyond one per register)."""
    written: set[int] = set()
    held = []
    for _ in range(len(inbound)):  # samples arriving meanwhile wait for the next tick
        item = inbound.popleft()
        reg, sample, in_order = item
        if id(reg) in written:
            if in_order:
                held.append(item)
                continue
            reg.superseded += 1
        reg.write(sample, now)
        written.add(id(reg))
    if held:
        inbound.extendleft(reversed(held))
    return bool(held)
