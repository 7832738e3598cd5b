"""The launcher's commands to one process of a split run: one line each on the process's stdin.

``finish FINISHED REASON``: process ``FINISHED`` ended normally; handle what the inputs already
sent, then stop (``umbra.runtime.links.process``). ``abort - REASON``: the run failed elsewhere
or was interrupted; stop now. The launcher writes lines with :meth:`ControlLine.encode` and the
process reads them with :func:`parse_control_line`: the format lives here only.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass


class ControlCommand(enum.Enum):
    """What the launcher tells a process."""

    FINISH = "finish"  #: another process ended normally: drain the inputs, then stop (status 0)
    ABORT = "abort"  #: stop now (status 1)


#: How long a process told to ``finish`` waits for its input streams to end [s].
FINISH_GRACE = 5.0
#: The ``FINISHED`` field of a line that names no process (an abort).
NO_PROCESS = "-"


@dataclass(frozen=True)
class ControlLine:
    """One command: what to do, the process whose end caused it (``finish``; else None) and
    the reason a person reads in the process's summary."""

    command: ControlCommand
    reason: str
    finished: str | None = None

    def encode(self) -> bytes:
        """The line the launcher writes (the reason's whitespace folded to single spaces)."""
        who = self.finished or NO_PROCESS
        return f"{self.command.value} {who} {' '.join(self.reason.split())}\n".encode()


def parse_control_line(line: str) -> ControlLine | str:
    """The command of ``line``, or what is wrong with it (a line from another version of the
    launcher, say: the process logs it and goes on)."""
    word, _, rest = line.strip().partition(" ")
    try:
        command = ControlCommand(word)
    except ValueError:
        return f"unknown launcher command {word!r} (expected one of {_names()})"
    who, _, reason = rest.partition(" ")
    finished = None if who in ("", NO_PROCESS) else who
    return ControlLine(command, reason, finished)


def _names() -> str:
    return ", ".join(c.value for c in ControlCommand)
