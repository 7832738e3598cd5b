"""A page socket's message budget: a token bucket and a count of bad messages (pure).

A page sends a few dozen small messages a second (jog keep-alives every 40 ms, a painted report
per frame); a socket beyond :data:`~umbra.connectors.limits.MAX_PAGE_MESSAGES_PER_S` sustained or
:data:`~umbra.connectors.limits.MAX_PAGE_MESSAGE_BURST` at once, or with more than
:data:`~umbra.connectors.limits.MAX_PAGE_BAD_MESSAGES` malformed ones, is not a page: it is closed.
"""

from __future__ import annotations

from dataclasses import dataclass

from umbra.connectors.limits import (
    MAX_PAGE_BAD_MESSAGES,
    MAX_PAGE_MESSAGE_BURST,
    MAX_PAGE_MESSAGES_PER_S,
)


@dataclass
class MessageBudget:
    """Budget of one socket; ``now`` is monotonic seconds."""

    rate: float = MAX_PAGE_MESSAGES_PER_S  #: sustained messages per second
    burst: float = MAX_PAGE_MESSAGE_BURST  #: messages at once
    max_bad: int = MAX_PAGE_BAD_MESSAGES
    tokens: float = -1.0
    last: float = 0.0
    bad: int = 0

    def spend(self, now: float) -> str:
        """Count one message; "" when within the budget, else why the socket must close."""
        if self.tokens < 0:
            self.tokens, self.last = self.burst, now
        self.tokens = min(self.burst, self.tokens + (now - self.last) * self.rate)
        self.last = now
        if self.tokens < 1.0:
            return (
                f"expected at most {self.rate:.0f} messages per second (bursts of "
                f"{self.burst:.0f}), found more"
            )
        self.tokens -= 1.0
        return ""

    def spoiled(self) -> str:
        """Count one malformed message; "" while under the limit, else why to close."""
        self.bad += 1
        if self.bad > self.max_bad:
            return f"expected well-formed messages, found {self.bad} malformed ones"
        return ""
