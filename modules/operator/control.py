"""Several viewers, one operator: who holds control of the console.

Any number of sessions (browser pages) watch; at most one holds control. Taking control is
refused while another session holds it (the holder releases it, or disconnects). Commands from
a session without control are refused and counted. Pure: no threads, no clock.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class Decision:
    """The outcome of a request: ``ok``, and the message for the page and the log."""

    ok: bool
    message: str


@dataclass
class ControlArbiter:
    """Sessions by id, the holder of control, and the refusals."""

    sessions: dict[str, str] = field(default_factory=dict)  #: id -> display name
    holder: str | None = None
    refused: int = 0
    #: True once any person has held control during the run (the simulated operator steps aside)
    person_acted: bool = False

    def join(self, session: str, name: str) -> None:
        """A page connected."""
        self.sessions[session] = name

    def leave(self, session: str) -> bool:
        """A page disconnected; True when it held control (which is now free)."""
        self.sessions.pop(session, None)
        if self.holder == session:
            self.holder = None
            return True
        return False

    def take(self, session: str) -> Decision:
        """``session`` asks for control."""
        if session not in self.sessions:
            self.refused += 1
            return Decision(False, "unknown session: reload the page")
        if self.holder == session:
            return Decision(True, "you already hold control")
        if self.holder is not None:
            self.refused += 1
            return Decision(
                False,
                f"refused: {self.sessions.get(self.holder, self.holder)} holds control; "
                "they must release it first",
            )
        self.holder = session
        self.person_acted = True
        return Decision(True, f"{self.sessions[session]} took control")

    def release(self, session: str) -> Decision:
        """``session`` gives control back."""
        if self.holder != session:
            self.refused += 1
            return Decision(False, "refused: you do not hold control")
        self.holder = None
        return Decision(True, f"{self.sessions.get(session, session)} released control")

    def may_command(self, session: str, what: str) -> Decision:
        """Whether ``session`` may send the command ``what`` (refusals are counted)."""
        if self.holder == session:
            return Decision(True, "")
        self.refused += 1
        if self.holder is None:
            return Decision(False, f"refused {what}: take control first")
        return Decision(
            False,
            f"refused {what}: {self.sessions.get(self.holder, self.holder)} holds control",
        )

    def holder_name(self) -> str:
        """Display name of the holder ("" when nobody holds control)."""
        return "" if self.holder is None else self.sessions.get(self.holder, self.holder)
