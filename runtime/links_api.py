"""The interface between the scheduler and a link transport (zenoh between processes).

The scheduler owns registers and output ports; a transport turns a cross-process connection into
a publisher (an output sink) on the producer's side and a subscription on the consumer's side.
Samples arrive on the transport's threads; ``deliver`` only queues them and ``arrived`` lets the
scheduler run a tick (on that thread when it is idle, else on its loop's), which writes them into
registers at its start; ticks never overlap, so modules never see concurrency.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol

from umbra.connectors.messages import Message
from umbra.connectors.ports import Sink
from umbra.runtime.graph.plan import LinkPlan


class LinkTransport(Protocol):
    """What a process needs from its links."""

    #: Changes whenever an answer of ``producer_alive`` may have changed, so the scheduler asks
    #: only after a change; None when the transport cannot say (then it asks on every tick).
    state_version: int | None

    def publisher(self, link: LinkPlan) -> Sink:
        """A sink that publishes samples of ``link`` (producer side)."""
        ...

    def subscribe(
        self,
        link: LinkPlan,
        deliver: Callable[[Message], None],
        arrived: Callable[[], None] | None = None,
    ) -> None:
        """Call ``deliver(sample)`` for each decoded sample of ``link`` (consumer side), then
        ``arrived()`` once the sample was given to every connection of its output."""
        ...

    def producer_alive(self, link: LinkPlan) -> bool:
        """Whether the process producing ``link`` is alive (liveliness) and its stream has not
        ended."""
        ...

    def clock_error(self, link: LinkPlan) -> float:
        """The bound [s] on the error of ``link``'s stamps and origins once on this process's
        clock (``umbra.runtime.links.clock_sync``); infinite until the producer's clock is
        measured."""
        ...

    def clock_problem(self, link: LinkPlan) -> str:
        """Why ``link``'s samples cannot be dated on this process's clock now (empty: they
        can)."""
        ...

    def stats(self) -> dict[str, object]:
        """Counters for the run summary (samples, decode errors...)."""
        ...

    def close(self) -> None:
        """Undeclare everything and close the session."""
        ...
