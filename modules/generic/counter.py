"""Counter: a source of consecutive integers, for wiring tests and link checks."""

from __future__ import annotations

from umbra.connectors import Module, Output, Parameters, param
from umbra.connectors.messages import Scalar


class Counter(Module["Counter.Params"]):
    """Sends start, start+step, ... one value per period, as events: every value reaches every
    consumer, in order (what a link check needs; a state stream would keep only the newest)."""

    class Params(Parameters):
        start: int = param(0, "first value")
        step_by: int = param(1, "increment per period")
        stop_after: int = param(0, "end the run after this many values (0: never)", ge=0)

    count = Output(Scalar, events=True, doc="the current count (every one delivered)")

    def start(self) -> None:
        self._next = self.params.start
        self._sent = 0

    def step(self, now: float) -> None:
        self.count.send(Scalar(value=float(self._next)))
        self._next += self.params.step_by
        self._sent += 1
        if self.params.stop_after and self._sent >= self.params.stop_after:
            self.context.request_stop(f"`{self.name}` sent {self._sent} values", 0)

    def summary(self) -> dict[str, object]:
        return {"sent": self._sent}
