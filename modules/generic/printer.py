"""Printer: logs samples of any type, at most ``max_rate_hz`` lines per second.

The limit is a credit that grows by ``max_rate_hz`` lines per second up to one line; a sample is
printed while the credit is at least half a line, and each print costs a whole one. A feed at the
limit therefore prints every sample even when arrivals jitter by up to half a period (or when
``now`` differences round just under the period: 0.7 - 0.6 < 0.1), and a faster feed prints
``max_rate_hz`` lines per second in the long run (a window of one second holds at most
``max_rate_hz + 1.5``).
"""

from __future__ import annotations

import numpy as np

from umbra.connectors import Input, Module, Parameters, param
from umbra.connectors.messages import Message


def format_sample(sample: Message, precision: int = 4) -> str:
    """A one-line, human-readable form of a sample (arrays shortened)."""
    parts = []
    for field in sample.__struct_fields__:
        if field in ("stamp", "origin"):
            continue
        value = getattr(sample, field)
        if isinstance(value, np.ndarray):
            text = (
                np.array2string(value, precision=precision, separator=",", threshold=8)
                if value.size <= 16
                else f"array{list(value.shape)}"
            )
        elif isinstance(value, float):
            text = f"{value:.{precision}g}"
        else:
            text = repr(value)
        parts.append(f"{field}={text}")
    return f"t={sample.stamp:.3f} {type(sample).__name__}(" + ", ".join(parts) + ")"


class Printer(Module["Printer.Params"]):
    """Prints each new sample on its input (rate-limited), for watching a connector."""

    class Params(Parameters):
        max_rate_hz: float = param(10.0, "at most this many lines per second", unit="Hz", gt=0)
        precision: int = param(4, "significant digits", ge=1, le=17)

    value = Input(Message, trigger=True, doc="any sample")

    def start(self) -> None:
        self._credit = 1.0
        self._credit_time: float | None = None
        self.printed = 0
        self.seen = 0

    def step(self, now: float) -> None:
        sample = self.value.get(now)
        if sample is None or not self.value.fresh:
            return
        self.seen += 1
        if self._credit_time is not None:
            earned = (now - self._credit_time) * self.params.max_rate_hz
            self._credit = min(1.0, self._credit + max(0.0, earned))
        self._credit_time = now
        if self._credit >= 0.5:
            self._credit -= 1.0
            self.printed += 1
            print(f"[{self.name}] {format_sample(sample, self.params.precision)}", flush=True)

    def summary(self) -> dict[str, object]:
        return {"seen": self.seen, "printed": self.printed}
