"""Reason codes with the operator's words declared beside them.

A module that stops, waits or fails says why twice: a *code* (an enum member, what other modules
and the station decide on) and the exact text (for logs and the station's detail, one click away;
free to change). The operator's words for a code are declared on the member itself, in the file
that defines the code::

    class GuardReason(Worded):
        WATCHDOG = "watchdog", "commands stopped arriving in time"

``GuardReason.WATCHDOG == "watchdog"`` (the code travels as that string), and
``GuardReason.WATCHDOG.words`` is what the operator reads. A member declared without words gets
"" and :func:`missing_words` names it (``tests/operator/test_reason_words.py`` fails on it).
"""

from __future__ import annotations

import enum
from collections.abc import Iterable
from typing import TypeVar

_C = TypeVar("_C", bound="Code")


class Code(str, enum.Enum):
    """A string enum (``enum.StrEnum`` before Python 3.11): each member is its code, a string,
    equal to it, printed and formatted as it, and sent as it (msgspec writes the value)."""

    def __str__(self) -> str:
        return str(self.value)

    def __format__(self, spec: str) -> str:
        return format(str(self.value), spec)

    @classmethod
    def listed(cls) -> str:
        """The codes as a person reads the choices: "a, b, c"."""
        return ", ".join(str(member) for member in cls)

    @classmethod
    def named(cls: type[_C], word: str, unknown: str, error: type[Exception] = ValueError) -> _C:
        """The member whose code is ``word`` (a person's or a file's); else ``error`` saying
        ``unknown`` (e.g. "unknown primitive kind"), the word and the codes there are."""
        try:
            return cls(word)
        except ValueError:
            raise error(f"{unknown} {word!r}; expected one of {cls.listed()}") from None


class Worded(Code):
    """A string enum whose members carry the operator's words: ``NAME = "code", "words"``."""

    words: str

    def __new__(cls, code: str, words: str = "") -> Worded:
        member = str.__new__(cls, code)
        member._value_ = code
        member.words = words
        return member


def missing_words(codes: type[Worded]) -> list[str]:
    """``Enum.MEMBER`` of every member of ``codes`` without operator words."""
    return [f"{codes.__name__}.{m.name}" for m in codes if not m.words.strip()]


def worded_enums() -> list[type[Worded]]:
    """Every :class:`Worded` enum defined so far (the base layer's once it is imported)."""
    found: list[type[Worded]] = []
    stack = list(Worded.__subclasses__())
    while stack:
        cls = stack.pop()
        found.append(cls)
        stack.extend(cls.__subclasses__())
    return sorted(found, key=lambda c: (c.__module__, c.__name__))


def words_of(codes: Iterable[Worded]) -> str:
    """The words of ``codes`` joined with "; ", each said once, in order ("" for none)."""
    said: list[str] = []
    for code in codes:
        if code.words not in said:
            said.append(code.words)
    return "; ".join(said)
