"""The operator's *Stop* as a judge of the run reads it: the one rule World and SketchWorld share.

The operator console's ``stop_run`` (the *Stop run* button, for the page that holds control)
sends a :class:`~umbra.connectors.commands.StopRun`; wired to a judge's ``operator`` input it ends
the run as a normal stop, whether attended or not (``ModuleContext.request_stop``, not
``end_run``), the judge's verdict saying :data:`STOPPED_BY_OPERATOR`. A second one changes
nothing. The console offers the button only when its ``stop_run`` is connected.
"""

from __future__ import annotations

from umbra.connectors import Input, Register
from umbra.connectors.commands import StopRun

#: the verdict of a run its operator ended with the console's *Stop*
STOPPED_BY_OPERATOR = "stopped by the operator"


def operator_input() -> Input:
    """A judge's ``operator`` input: the console's *Stop* (wire ``console.stop_run`` here)."""
    return Input(
        StopRun,
        required=False,
        feedback=True,
        doc="the operator console's *Stop*: ends the run (verdict 'stopped by the operator')",
    )


class OperatorStop:
    """Whether the operator's *Stop* arrived: ``requested`` says True once, on the first new
    one read from the judge's ``operator`` input; ``stopped`` stays True after it."""

    def __init__(self) -> None:
        self.stopped = False

    def requested(self, port: Register[StopRun], now: float) -> bool:
        """True at the first fresh *Stop* on ``port`` (the judge's ``operator`` register) at
        ``now`` [s], False before and ever after."""
        command = port.get(now)
        if self.stopped or command is None or not port.fresh:
            return False
        self.stopped = True
        return True
