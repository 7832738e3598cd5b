"""CiA 402 power state machine: statusword decoding, controlword commands, transitions.

Pure functions on integers, shared by the simulated drive (drive side: which state a
controlword leads to) and the master (which controlword moves a drive towards
Operation enabled). Bit layouts follow CiA 402 / IEC 61800-7-201:

statusword bits: 0 ready to switch on, 1 switched on, 2 operation enabled, 3 fault,
4 voltage enabled, 5 quick stop (active low), 6 switch on disabled, 7 warning, 9 remote,
10 target reached, 11 internal limit active.

controlword bits: 0 switch on, 1 enable voltage, 2 quick stop (active low),
3 enable operation, 7 fault reset (acts on its rising edge).
"""

from __future__ import annotations

import enum


class State(enum.Enum):
    """Power states of a CiA 402 drive."""

    NOT_READY_TO_SWITCH_ON = "not ready to switch on"
    SWITCH_ON_DISABLED = "switch on disabled"
    READY_TO_SWITCH_ON = "ready to switch on"
    SWITCHED_ON = "switched on"
    OPERATION_ENABLED = "operation enabled"
    QUICK_STOP_ACTIVE = "quick stop active"
    FAULT_REACTION_ACTIVE = "fault reaction active"
    FAULT = "fault"


class Command(enum.Enum):
    """Device control commands encoded in the controlword."""

    SHUTDOWN = "shutdown"
    SWITCH_ON = "switch on"  # also "disable operation" when in Operation enabled
    ENABLE_OPERATION = "enable operation"
    DISABLE_VOLTAGE = "disable voltage"
    QUICK_STOP = "quick stop"
    FAULT_RESET = "fault reset"


SW_READY_TO_SWITCH_ON = 1 << 0
SW_SWITCHED_ON = 1 << 1
SW_OPERATION_ENABLED = 1 << 2
SW_FAULT = 1 << 3
SW_VOLTAGE_ENABLED = 1 << 4
SW_QUICK_STOP = 1 << 5
SW_SWITCH_ON_DISABLED = 1 << 6
SW_WARNING = 1 << 7
SW_REMOTE = 1 << 9
SW_TARGET_REACHED = 1 << 10

CW_FAULT_RESET = 1 << 7

# (mask, value) of the statusword for each state, in decoding order.
_STATE_PATTERNS: tuple[tuple[int, int, State], ...] = (
    (0x4F, 0x00, State.NOT_READY_TO_SWITCH_ON),
    (0x4F, 0x40, State.SWITCH_ON_DISABLED),
    (0x6F, 0x21, State.READY_TO_SWITCH_ON),
    (0x6F, 0x23, State.SWITCHED_ON),
    (0x6F, 0x27, State.OPERATION_ENABLED),
    (0x6F, 0x07, State.QUICK_STOP_ACTIVE),
    (0x4F, 0x0F, State.FAULT_REACTION_ACTIVE),
    (0x4F, 0x08, State.FAULT),
)

# Low statusword bits (0..6) a drive reports in each state.
_STATE_BITS: dict[State, int] = {
    State.NOT_READY_TO_SWITCH_ON: 0x00,
    State.SWITCH_ON_DISABLED: 0x40,
    State.READY_TO_SWITCH_ON: 0x21,
    State.SWITCHED_ON: 0x33,
    State.OPERATION_ENABLED: 0x37,
    State.QUICK_STOP_ACTIVE: 0x17,
    State.FAULT_REACTION_ACTIVE: 0x1F,
    State.FAULT: 0x08,
}

_CONTROLWORDS: dict[Command, int] = {
    Command.SHUTDOWN: 0x06,
    Command.SWITCH_ON: 0x07,
    Command.ENABLE_OPERATION: 0x0F,
    Command.DISABLE_VOLTAGE: 0x00,
    Command.QUICK_STOP: 0x02,
    Command.FAULT_RESET: 0x80,
}

# Quick stop option codes (0x605A) after which the drive stays in Quick stop active.
QUICK_STOP_OPTIONS_STAYING = frozenset({5, 6, 7, 8})


class StatuswordError(ValueError):
    """A statusword that matches no CiA 402 state."""


def state_from_statusword(statusword: int) -> State:
    """Decode the power state from a 16-bit statusword (0x6041)."""
    for mask, value, state in _STATE_PATTERNS:
        if statusword & mask == value:
            return state
    raise StatuswordError(f"statusword 0x{statusword:04X} matches no CiA 402 state")


def statusword_for(state: State, *, target_reached: bool = False, warning: bool = False) -> int:
    """Statusword a drive in `state` reports (remote bit set)."""
    word = _STATE_BITS[state] | SW_REMOTE
    if target_reached:
        word |= SW_TARGET_REACHED
    if warning:
        word |= SW_WARNING
    return word


def controlword_for(command: Command) -> int:
    """Controlword (0x6040) that encodes `command`.

    FAULT_RESET acts on the rising edge of bit 7: send a controlword without bit 7
    (e.g. DISABLE_VOLTAGE) before it.
    """
    return _CONTROLWORDS[command]


def command_from_controlword(controlword: int, previous_controlword: int) -> Command:
    """Decode the command in a controlword; fault reset needs a 0->1 edge of bit 7."""
    if controlword & CW_FAULT_RESET and not previous_controlword & CW_FAULT_RESET:
        return Command.FAULT_RESET
    if not controlword & 0x02:
        return Command.DISABLE_VOLTAGE
    if not controlword & 0x04:
        return Command.QUICK_STOP
    if not controlword & 0x01:
        return Command.SHUTDOWN
    if not controlword & 0x08:
        return Command.SWITCH_ON
    return Command.ENABLE_OPERATION


def next_state(state: State, command: Command, quick_stop_option: int = 2) -> State:
    """Drive-side transition for a commanded controlword (CiA 402 transitions 2..12, 15, 16).

    Automatic transitions (power-up, end of fault reaction, end of a quick stop ramp) are
    not commands and are left to the drive. A command that is not allowed in `state`
    leaves the state unchanged.
    """
    if state is State.FAULT:
        return State.SWITCH_ON_DISABLED if command is Command.FAULT_RESET else state
    if state in (State.NOT_READY_TO_SWITCH_ON, State.FAULT_REACTION_ACTIVE):
        return state
    if command is Command.DISABLE_VOLTAGE:
        return State.SWITCH_ON_DISABLED
    if state is State.QUICK_STOP_ACTIVE:
        if command is Command.ENABLE_OPERATION and quick_stop_option in QUICK_STOP_OPTIONS_STAYING:
            return State.OPERATION_ENABLED
        return state
    if command is Command.QUICK_STOP:
        if state is State.OPERATION_ENABLED:
            return State.QUICK_STOP_ACTIVE
        return State.SWITCH_ON_DISABLED if state is not State.SWITCH_ON_DISABLED else state
    transitions: dict[tuple[State, Command], State] = {
        (State.SWITCH_ON_DISABLED, Command.SHUTDOWN): State.READY_TO_SWITCH_ON,
        (State.READY_TO_SWITCH_ON, Command.SWITCH_ON): State.SWITCHED_ON,
        (State.READY_TO_SWITCH_ON, Command.ENABLE_OPERATION): State.OPERATION_ENABLED,
        (State.SWITCHED_ON, Command.ENABLE_OPERATION): State.OPERATION_ENABLED,
        (State.SWITCHED_ON, Command.SHUTDOWN): State.READY_TO_SWITCH_ON,
        (State.OPERATION_ENABLED, Command.SWITCH_ON): State.SWITCHED_ON,
        (State.OPERATION_ENABLED, Command.SHUTDOWN): State.READY_TO_SWITCH_ON,
    }
    return transitions.get((state, command), state)


def command_towards_operation_enabled(state: State) -> Command | None:
    """Master side: the next command on the path to Operation enabled.

    None when the drive is already there or must get there by itself (power-up, fault
    reaction); FAULT_RESET needs bit 7 low in the controlword sent before it.
    """
    return {
        State.FAULT: Command.FAULT_RESET,
        State.SWITCH_ON_DISABLED: Command.SHUTDOWN,
        State.READY_TO_SWITCH_ON: Command.SWITCH_ON,
        State.SWITCHED_ON: Command.ENABLE_OPERATION,
        State.QUICK_STOP_ACTIVE: Command.DISABLE_VOLTAGE,
    }.get(state)
