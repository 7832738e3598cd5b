"""Errors a user can cause, and how they are reported.

A :class:`UserError` is raised for anything the user can fix (a graph file, a parameter, a
calibration
file, a command line). The CLI prints its message without a traceback and exits with status 2.
"""

from __future__ import annotations

from dataclasses import dataclass


class UserError(Exception):
    """A problem in the user's input: printed as is, exit status 2, no traceback."""


@dataclass(frozen=True)
class Location:
    """A place in a user's file: 1-based line and column (column 0 means "whole line")."""

    file: str
    line: int
    column: int = 0

    def __str__(self) -> str:
        if self.line <= 0:
            return self.file
        if self.column:
            return f"{self.file}:{self.line}:{self.column}"
        return f"{self.file}:{self.line}"


@dataclass(frozen=True)
class Diagnostic:
    """One problem found while checking a file, with its place and an optional hint."""

    location: Location
    message: str
    hint: str = ""

    def __str__(self) -> str:
        text = f"{self.location}: error: {self.message}"
        if self.hint:
            text += f" ({self.hint})"
        return text


class CheckFailed(UserError):
    """Checking found one or more problems; ``str()`` lists all of them, one per line."""

    def __init__(self, diagnostics: list[Diagnostic]) -> None:
        self.diagnostics = list(diagnostics)
        super().__init__("\n".join(str(d) for d in self.diagnostics))


class ModuleFailed(Exception):
    """A module raised during start, step or stop; the run stops cleanly with exit status 1."""

    def __init__(self, module: str, type_name: str, phase: str, tick: int, cause: BaseException):
        self.module = module
        self.type_name = type_name
        self.phase = phase
        self.tick = tick
        self.cause = cause
        super().__init__(
            f"module `{module}` ({type_name}) raised in {phase} at tick {tick}: "
            f"{type(cause).__name__}: {cause}"
        )
