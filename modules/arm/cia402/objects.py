"""Object dictionary entries of a CiA 402 drive used in profile velocity mode.

Indexes of CiA 301 communication objects and CiA 402 drive objects, and the path of the
minimal EDS shipped with this package (used by the simulated drive and as the master's
default object dictionary). Units on the drive side are counts, counts/s, counts/s^2.
"""

from __future__ import annotations

from pathlib import Path

DEVICE_TYPE = 0x1000
ERROR_REGISTER = 0x1001
CONSUMER_HEARTBEAT_TIME = 0x1016  # sub 1..n: node id << 16 | ms
PRODUCER_HEARTBEAT_TIME = 0x1017  # ms
IDENTITY = 0x1018

COMMUNICATION_LOSS_COUNT = 0x2000  # manufacturer object of the simulated drive

ERROR_CODE = 0x603F
ABORT_CONNECTION_OPTION_CODE = 0x6007
CONTROLWORD = 0x6040
STATUSWORD = 0x6041
QUICK_STOP_OPTION_CODE = 0x605A
MODES_OF_OPERATION = 0x6060
MODES_OF_OPERATION_DISPLAY = 0x6061
POSITION_ACTUAL = 0x6064  # counts
VELOCITY_ACTUAL = 0x606C  # counts/s
PROFILE_ACCELERATION = 0x6083  # counts/s^2
PROFILE_DECELERATION = 0x6084  # counts/s^2
QUICK_STOP_DECELERATION = 0x6085  # counts/s^2
MAX_DECELERATION = 0x60C6  # counts/s^2
TARGET_VELOCITY = 0x60FF  # counts/s
SUPPORTED_DRIVE_MODES = 0x6502

RPDO_COMM_FIRST = 0x1400
PDO_EVENT_TIMER_SUBINDEX = 5  # ms; for an RPDO: deadline monitoring
RPDO_MAP_FIRST = 0x1600
TPDO_COMM_FIRST = 0x1800
TPDO_MAP_FIRST = 0x1A00
PDO_PARAMETER_LAST = 0x1BFF

SYNC_COB_ID = 0x080
HEARTBEAT_COB_BASE = 0x700  # + node id

PROFILE_VELOCITY_MODE = 3
SUPPORTED_MODE_PV_BIT = 1 << 2  # bit of 0x6502 for profile velocity
DEVICE_PROFILE_402 = 402  # low 16 bits of 0x1000

INT32_MIN = -(1 << 31)
INT32_MAX = (1 << 31) - 1

EDS_PATH: Path = Path(__file__).with_name("cia402_drive.eds")


def is_pdo_parameter(index: int) -> bool:
    """True for PDO communication and mapping parameter indexes (0x1400..0x1BFF)."""
    return RPDO_COMM_FIRST <= index <= PDO_PARAMETER_LAST
