"""CiA 402 power state machine: decoding, commands, transitions, the master's path."""

from __future__ import annotations

import pytest

from umbra.modules.arm.cia402.state_machine import (
    Command,
    State,
    StatuswordError,
    command_from_controlword,
    command_towards_operation_enabled,
    controlword_for,
    next_state,
    state_from_statusword,
    statusword_for,
)

# Statuswords as the CiA 402 table gives them (x bits = 0), with extra bits set to show
# that only the state bits matter.
TABLE = [
    (0x0000, State.NOT_READY_TO_SWITCH_ON),
    (0x0040, State.SWITCH_ON_DISABLED),
    (0x0021, State.READY_TO_SWITCH_ON),
    (0x0023, State.SWITCHED_ON),
    (0x0027, State.OPERATION_ENABLED),
    (0x0007, State.QUICK_STOP_ACTIVE),
    (0x000F, State.FAULT_REACTION_ACTIVE),
    (0x0008, State.FAULT),
]


@pytest.mark.parametrize(("word", "state"), TABLE)
def test_statusword_decodes_to_the_table_state(word: int, state: State) -> None:
    assert state_from_statusword(word) is state
    assert state_from_statusword(word | 0x0610) is state  # voltage, remote, target reached


@pytest.mark.parametrize("state", list(State))
def test_statusword_for_round_trips(state: State) -> None:
    assert state_from_statusword(statusword_for(state, target_reached=True)) is state


def test_undefined_statusword_is_an_error() -> None:
    with pytest.raises(StatuswordError, match="0x0001"):
        state_from_statusword(0x0001)


@pytest.mark.parametrize("command", [c for c in Command if c is not Command.FAULT_RESET])
def test_controlword_decodes_to_its_command(command: Command) -> None:
    assert command_from_controlword(controlword_for(command), 0) is command


def test_fault_reset_needs_a_rising_edge_of_bit_7() -> None:
    assert command_from_controlword(0x80, 0x00) is Command.FAULT_RESET
    assert command_from_controlword(0x80, 0x80) is not Command.FAULT_RESET


def test_enable_sequence_of_the_standard() -> None:
    state = State.SWITCH_ON_DISABLED
    for command, expected in [
        (Command.SHUTDOWN, State.READY_TO_SWITCH_ON),
        (Command.SWITCH_ON, State.SWITCHED_ON),
        (Command.ENABLE_OPERATION, State.OPERATION_ENABLED),
        (Command.SWITCH_ON, State.SWITCHED_ON),  # disable operation (5)
        (Command.SHUTDOWN, State.READY_TO_SWITCH_ON),  # (6)
        (Command.DISABLE_VOLTAGE, State.SWITCH_ON_DISABLED),  # (7)
    ]:
        state = next_state(state, command)
        assert state is expected


def test_quick_stop_and_its_option_codes() -> None:
    assert next_state(State.OPERATION_ENABLED, Command.QUICK_STOP) is State.QUICK_STOP_ACTIVE
    assert next_state(State.SWITCHED_ON, Command.QUICK_STOP) is State.SWITCH_ON_DISABLED
    # Back to Operation enabled only with options 5..8 (transition 16).
    assert next_state(State.QUICK_STOP_ACTIVE, Command.ENABLE_OPERATION, 2) is (
        State.QUICK_STOP_ACTIVE
    )
    assert next_state(State.QUICK_STOP_ACTIVE, Command.ENABLE_OPERATION, 6) is (
        State.OPERATION_ENABLED
    )
    assert next_state(State.QUICK_STOP_ACTIVE, Command.DISABLE_VOLTAGE) is State.SWITCH_ON_DISABLED


def test_fault_leaves_only_by_fault_reset() -> None:
    for command in Command:
        expected = State.SWITCH_ON_DISABLED if command is Command.FAULT_RESET else State.FAULT
        assert next_state(State.FAULT, command) is expected


@pytest.mark.parametrize(
    "start",
    [
        State.SWITCH_ON_DISABLED,
        State.READY_TO_SWITCH_ON,
        State.SWITCHED_ON,
        State.QUICK_STOP_ACTIVE,
        State.FAULT,
    ],
)
def test_master_path_reaches_operation_enabled(start: State) -> None:
    state, steps = start, 0
    while state is not State.OPERATION_ENABLED:
        command = command_towards_operation_enabled(state)
        assert command is not None
        state = next_state(state, command)
        steps += 1
        assert steps <= 4
    assert command_towards_operation_enabled(state) is None
