"""The launcher's command lines to a process (``umbra.runtime.links.control_line``)."""

from __future__ import annotations

from umbra.runtime.links.control_line import (
    ControlCommand,
    ControlLine,
    parse_control_line,
)


def test_a_finish_names_the_process_that_ended_and_keeps_the_reason() -> None:
    line = ControlLine(ControlCommand.FINISH, "process `smart` finished:\n  grasped", "smart")
    assert line.encode() == b"finish smart process `smart` finished: grasped\n"
    assert parse_control_line(line.encode().decode()) == ControlLine(
        ControlCommand.FINISH, "process `smart` finished: grasped", "smart"
    )


def test_an_abort_names_no_process() -> None:
    line = ControlLine(ControlCommand.ABORT, "interrupted by SIGINT")
    assert line.encode() == b"abort - interrupted by SIGINT\n"
    assert parse_control_line("abort - interrupted by SIGINT\n") == line
    assert parse_control_line("abort") == ControlLine(ControlCommand.ABORT, "")


def test_an_unknown_command_says_what_was_expected() -> None:
    told = parse_control_line("pause - for a while")
    assert told == "unknown launcher command 'pause' (expected one of finish, abort)"
