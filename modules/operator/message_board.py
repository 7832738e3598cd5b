"""The station's Messages panel: what happened, in the operator's words, each once.

A message that repeats (the same words to the same pages) is not a new line: its count grows
and it moves to the top, so a reason said five times is shown once with "×5". An error said
again with other numbers only (a burst of refusals "stale page: the image you acted on is 1.128 s
old ...", each with its own age or frame) is a repeat too: one line, with the newest numbers and
the count; information is a repeat only in the same words ("viewer 2 is watching" and "viewer 3
is watching" are two people). So a burst is one line and the panel's lines stay few. The exact text
behind a plain message (a module's full reason) is kept as its ``detail``, shown on a click; the
plain words come from the reason's code (``umbra.connectors.reasons``). Pure: no clock (times
are passed in, seconds of the run).
"""

from __future__ import annotations

import re
from dataclasses import asdict, dataclass

#: a number in a message (an age, a bound, a frame): "1.128", "0.5", "412", "-3e-05"
_NUMBER = re.compile(r"[-+]?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?")


def same_line_key(to: str, level: str, text: str) -> tuple[str, str, str]:
    """What makes two messages one line: the pages they go to, their level and their words;
    an error's numbers are left out (a repeated refusal with a new age is the same refusal)."""
    return to, level, _NUMBER.sub("#", text) if level == "error" else text


@dataclass
class Message:
    """One line of the panel: ``to`` a session ("*": every page), ``level`` info or error."""

    id: int
    to: str
    level: str
    text: str
    detail: str
    count: int
    t: float  #: when it was last said [s of the run]


class MessageBoard:
    """The last ``size`` distinct messages, newest last; ``id`` grows with every post (a page
    redraws when the newest id changed)."""

    def __init__(self, size: int = 30) -> None:
        if size < 1:
            raise ValueError(f"size must be >= 1, got {size}")
        self.size = size
        self.lines: list[Message] = []
        self.last_id = 0

    def post(
        self, text: str, t: float, to: str = "*", level: str = "info", detail: str = ""
    ) -> None:
        """Say ``text`` (with the exact ``detail`` behind it, "" none) at time ``t`` [s]; a
        repeat (:func:`same_line_key`) counts on its line, which takes the newest words."""
        self.last_id += 1
        key = same_line_key(to, level, text)
        for i, line in enumerate(self.lines):
            if same_line_key(line.to, line.level, line.text) == key:
                del self.lines[i]
                line.id, line.count, line.t, line.text = self.last_id, line.count + 1, t, text
                line.detail = detail or line.detail
                self.lines.append(line)
                return
        self.lines.append(Message(self.last_id, to, level, text, detail, 1, t))
        del self.lines[: -self.size]

    def post_reason(
        self, lead: str, plain: str, reason: str, t: float, to: str = "*", level: str = "error"
    ) -> None:
        """``lead`` and a reason in ``plain`` words (its code's), the ``reason`` as it came kept
        as the detail."""
        text = f"{lead}: {plain}" if plain else lead
        self.post(text, t, to, level, detail=reason if reason != plain else "")

    def for_page(self) -> list[dict[str, object]]:
        """Every line as JSON-ready dicts, newest first (each page keeps those ``to`` it)."""
        return [asdict(line) for line in reversed(self.lines)]
