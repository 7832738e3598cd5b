"""CANopen backend of WOLVERINE_JNTS: CiA 402 drives in profile velocity mode.

`Cia402Arm` (network.py) is the master; `SimDrive` (sim_drive.py) a simulated drive for
tests and hardware-free runs; `cia402_drive.eds` the minimal object dictionary both use.
"""

from umbra.modules.arm.cia402.bring_up import DriveStartError
from umbra.modules.arm.cia402.config import (
    BusSpec,
    BusSpecError,
    Cia402ArmConfig,
    Cia402ConfigError,
    JointDrive,
)
from umbra.modules.arm.cia402.network import Cia402Arm
from umbra.modules.arm.cia402.sim_drive import SimDrive
from umbra.modules.arm.cia402.status import ArmState, ArmStatus, DriveTrip, JointFeedback, TripCause

__all__ = [
    "ArmState",
    "ArmStatus",
    "BusSpec",
    "BusSpecError",
    "Cia402Arm",
    "Cia402ArmConfig",
    "Cia402ConfigError",
    "DriveStartError",
    "DriveTrip",
    "JointDrive",
    "JointFeedback",
    "SimDrive",
    "TripCause",
]
