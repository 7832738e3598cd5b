"""Log lines that a flood cannot turn into a flood of lines: at most one per key and period."""

from __future__ import annotations

import logging
import time

#: At most one log line per key and this many seconds (refused or undecodable samples, forged
#: tokens).
ERROR_LOG_PERIOD = 5.0


class RateLimitedLog:
    """Warnings of ``log``, at most one per key every ``period`` seconds; the lines held back
    are counted and said with the next one. Any thread may call it."""

    def __init__(self, log: logging.Logger, period: float = ERROR_LOG_PERIOD) -> None:
        self._log = log
        self.period = period
        self._last: dict[str, tuple[float, int]] = {}  # key -> (last line's time, held back)

    def warning(self, key: str, message: str, *args: object) -> bool:
        """Log ``message % args`` (with the count held back since the last line) unless a line
        of ``key`` went out less than ``period`` seconds ago; True when it was logged."""
        now = time.monotonic()
        last, quiet = self._last.get(key, (-self.period - 1.0, 0))
        if now - last < self.period:
            self._last[key] = (last, quiet + 1)
            return False
        more = f" ({quiet} more since the last report)" if quiet else ""
        self._log.warning(message + "%s", *args, more)
        self._last[key] = (now, 0)
        return True
