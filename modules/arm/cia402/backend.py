"""WOLVERINE_JNTS's `canopen` backend: the arm's joints on CiA 402 drives (`Cia402Arm`).

Built from WOLVERINE_JNTS's `canopen_config` YAML file (format: config_yaml.py). Joint order
and names come from the arm's DH table; the file lists every joint by name. Commands are
clipped to the table's rate limits, and a joint at a limit may only move back inside
(the drives' own software limits, 0x607D, remain the first line of defence).

With `simulate: true` the backend also runs one `SimDrive` per joint on the virtual bus, so
a graph can exercise the whole CANopen path without hardware (initial angles from
WOLVERINE_JNTS's `initial_q_deg`).

The drives run on wall time whatever the run's clock: `now` is not used for timing.
"""

from __future__ import annotations

import dataclasses
import logging
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from umbra.modules.arm.cia402.config import Cia402ArmConfig, Cia402ConfigError
from umbra.modules.arm.cia402.config_yaml import CanopenSettings, load_canopen_settings
from umbra.modules.arm.cia402.network import Cia402Arm
from umbra.modules.arm.cia402.sim_drive import SimDrive
from umbra.modules.arm.cia402.status import ArmState
from umbra.modules.arm.cia402.units import angles_to_counts
from umbra.modules.arm.dh import DHTable
from umbra.modules.arm.joints_backend import BackendError, JointReading, JointsBackend

logger = logging.getLogger(__name__)


def guard_rates(
    rates: ArrayLike,
    q: ArrayLike,
    q_min: ArrayLike,
    q_max: ArrayLike,
    qd_max: ArrayLike,
) -> NDArray[np.float64]:
    """Clip joint rates (rad/s) to ±qd_max; zero those that push a joint beyond its limits.

    Joints whose angle is unknown (NaN) get no limit check (their drive holds them).
    """
    out = np.clip(np.asarray(rates, dtype=float), -np.asarray(qd_max), np.asarray(qd_max))
    q = np.asarray(q, dtype=float)
    outward = ((q >= q_max) & (out > 0)) | ((q <= q_min) & (out < 0))
    out[outward] = 0.0
    return out


def order_like_table(config: Cia402ArmConfig, table: DHTable, source: str) -> Cia402ArmConfig:
    """The config with its joints in the table's order; every table joint exactly once."""
    by_name = {j.name: j for j in config.joints}
    missing = [n for n in table.names if n not in by_name]
    extra = [n for n in by_name if n not in table.names]
    if missing or extra:
        raise BackendError(
            f"{source}: joints {sorted(by_name)} do not match the arm's {list(table.names)}"
            + (f"; missing {missing}" if missing else "")
            + (f"; unknown {extra}" if extra else "")
        )
    return dataclasses.replace(config, joints=tuple(by_name[n] for n in table.names))


class Cia402Backend(JointsBackend):
    """Joint driver on CiA 402 drives over CANopen (profile velocity mode)."""

    def __init__(
        self,
        table: DHTable,
        settings: CanopenSettings,
        initial_q: ArrayLike | None = None,
    ) -> None:
        self.table = table
        self.joint_names = table.names
        self.settings = settings
        self.arm = Cia402Arm(settings.arm)
        self._initial_q = None if initial_q is None else np.asarray(initial_q, dtype=float)
        self._sim_drives: list[SimDrive] = []
        self._closed_losses = 0  # master losses of simulated drives already closed

    @classmethod
    def from_module(cls, table: DHTable, params: Any, context: Any) -> Cia402Backend:
        source = params.canopen_config
        if not source:
            raise BackendError(
                "the canopen backend needs canopen_config: a YAML file of the bus and the "
                "drives (format: modules/arm/cia402/config_yaml.py)"
            )
        try:
            settings = load_canopen_settings(source)
        except Cia402ConfigError as exc:
            raise BackendError(str(exc)) from None
        arm = order_like_table(settings.arm, table, source)
        settings = CanopenSettings(arm=arm, simulate=settings.simulate)
        initial_q = None
        if getattr(params, "initial_q_deg", None) is not None:
            initial_q = np.radians(np.asarray(params.initial_q_deg, dtype=float))
            if initial_q.shape != (table.n,):
                raise BackendError(
                    f"initial_q_deg needs {table.n} angles (one per joint), got {initial_q.size}"
                )
        if getattr(context, "clock", "real") == "sim":
            logger.info("canopen backend: the drives run on wall time, not on the sim clock")
        return cls(table, settings, initial_q)

    @property
    def sim_drives(self) -> tuple[SimDrive, ...]:
        """The simulated drives while running with `simulate: true` (for tests and demos)."""
        return tuple(self._sim_drives)

    def start(self) -> None:
        if self.settings.simulate:
            self._start_sim_drives()
        try:
            self.arm.start()
        except BaseException:
            self._close_sim_drives()
            raise

    def read(self, now: float) -> JointReading:
        feedback = self.arm.read()
        status = self.arm.status()
        return JointReading(
            position=feedback.positions_rad,
            velocity=feedback.velocities_rad_s,
            ok=status.state is ArmState.RUNNING and not status.trips,
            message=status.message,
        )

    def command(self, rates: ArrayLike, now: float) -> bool:
        q = self.arm.read().positions_rad
        t = self.table
        return self.arm.set_velocities(guard_rates(rates, q, t.q_min, t.q_max, t.qd_max))

    def stop(self) -> None:
        try:
            self.arm.stop()
        finally:
            self._close_sim_drives()

    def _start_sim_drives(self) -> None:
        config = self.settings.arm
        q0 = np.zeros(len(config.joints)) if self._initial_q is None else self._initial_q
        cpr = [j.counts_per_rad for j in config.joints]
        zero = [j.zero_counts for j in config.joints]
        counts = angles_to_counts(q0, cpr, zero)
        for joint, position in zip(config.joints, counts, strict=True):
            drive = SimDrive(joint.node_id, eds=config.eds, position_counts=float(position))
            self._sim_drives.append(drive)
            drive.connect(
                interface=config.bus.interface,
                channel=config.bus.channel,
                bitrate=config.bus.bitrate,
            )

    def counters(self) -> dict[str, int]:
        """Simulated drives: how often their own watchdog found the master silent."""
        if not self.settings.simulate:
            return {}
        losses = sum(d.master_losses for d in self._sim_drives)
        return {"drive_master_losses": self._closed_losses + losses}

    def _close_sim_drives(self) -> None:
        drives, self._sim_drives = self._sim_drives, []
        for drive in drives:
            self._closed_losses += drive.master_losses
            drive.close()
