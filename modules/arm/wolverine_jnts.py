"""WOLVERINE_JNTS: drives the arm's joints (simulated, or CiA 402 drives over CANopen)."""

from __future__ import annotations

from typing import Literal

import numpy as np
from msgspec.structs import replace
from pydantic import model_validator

from umbra.connectors import Input, Module, Output, ParamProblem, UserError, from_param, param
from umbra.connectors.commands import GripperCommand
from umbra.connectors.limits import MAX_COMMAND_AGE_S, MAX_JOINT_ACCEL_RAD_S2
from umbra.connectors.messages import JointRates, JointState, Status
from umbra.modules.arm.arm_params import ArmParams
from umbra.modules.arm.dh import DHTable
from umbra.modules.arm.joints_backend import BackendError, JointsBackend, backend_class


class WolverineJnts(Module["WolverineJnts.Params"]):
    """Joint driver: joint-rate commands in, joint state out, gripper commands.

    Backends: ``sim`` (integration with rate, acceleration and joint limits, a first-order lag,
    and an optional unknown calibration error between reported and true angles) and ``canopen``
    (CiA 402 drives, see ``modules/arm/cia402``). Rates must come through a safety guard
    (REG_VEL) and carry this arm's joint names; rates older than ``max_command_age`` or for other
    joints are replaced by zero. Give it a ``rate``: it publishes the state every tick.
    """

    TYPE = "WOLVERINE_JNTS"

    class Params(ArmParams):
        backend: Literal["sim", "canopen"] = param("sim", "joint driver")
        max_command_age: float = param(
            0.1,
            "older rate commands count as zero",
            unit="s",
            gt=0,
            le=MAX_COMMAND_AGE_S,
            safety=True,
        )
        initial_q_deg: list[float] | None = param(
            None, "sim: initial joint angles (default zeros, clipped to limits)", unit="deg"
        )
        accel_max: float = param(
            8.0,
            "sim: joint acceleration limit",
            unit="rad/s^2",
            gt=0,
            le=MAX_JOINT_ACCEL_RAD_S2,
            safety=True,
        )
        lag_tau: float = param(0.02, "sim: time constant of the rate response", unit="s", ge=0)
        calibration_error_deg: list[float] = param(
            [], "sim: unknown offsets, true minus reported angles (empty: none)", unit="deg"
        )
        gripper_travel_time: float = param(0.5, "sim: full gripper travel", unit="s", gt=0)
        drive_watchdog: float = param(
            0.1,
            "sim: the drive's own command timeout; a rate is obeyed this long at most after the "
            "last command, then the joints stop (canopen: heartbeat consumer in its YAML file)",
            unit="s",
            gt=0,
            le=MAX_COMMAND_AGE_S,
        )
        gripper_initial: float = param(1.0, "sim: initial gripper opening 0..1", ge=0, le=1)
        canopen_config: str = param("", "canopen: YAML file of the bus and the drives")

        def rate_problem(self, rate_hz: float | None) -> str:
            """The sim drive's watchdog must not cut a rate between two regular commands."""
            least = 2.0 / self.drive_watchdog
            if self.backend == "sim" and rate_hz is not None and rate_hz < least:
                return (
                    f"rate {rate_hz:g} Hz is too slow for drive_watchdog "
                    f"{self.drive_watchdog:g} s: the joints must be commanded at least twice "
                    f"per watchdog time ({least:g} Hz)"
                )
            return ""

        @model_validator(mode="after")
        def _one_value_per_joint(self) -> WolverineJnts.Params:
            n = self.table.n
            if self.initial_q_deg is not None and len(self.initial_q_deg) != n:
                raise ParamProblem(
                    "initial_q_deg",
                    f"needs {n} angles, one per joint {list(self.table.names)}, "
                    f"found {len(self.initial_q_deg)}",
                )
            if self.initial_q_deg is not None:
                q = np.radians(np.asarray(self.initial_q_deg, dtype=float))
                outside = [
                    f"{name} {deg:g}"
                    for name, deg, value, low, high in zip(
                        self.table.names,
                        self.initial_q_deg,
                        q,
                        self.table.q_min,
                        self.table.q_max,
                        strict=True,
                    )
                    if not low <= value <= high
                ]
                if outside:
                    raise ParamProblem(
                        "initial_q_deg",
                        f"has angles outside the joint limits: {', '.join(outside)} deg",
                    )
            if self.calibration_error_deg and len(self.calibration_error_deg) != n:
                raise ParamProblem(
                    "calibration_error_deg",
                    f"needs {n} angles (or none), one per joint {list(self.table.names)}, "
                    f"found {len(self.calibration_error_deg)}",
                )
            if self.backend == "canopen":
                _check_canopen_config(self.canopen_config, self.table)
            return self

    rates = Input(
        JointRates, joints=from_param("joint_names"), requires_guard=True, doc="joint rates"
    )
    gripper_in = Input(
        GripperCommand, required=False, requires_guard=True, doc="gripper: open / close"
    )
    joint_state = Output(
        JointState, joints=from_param("joint_names"), measured=True, doc="reported joints"
    )
    true_joint_state = Output(
        JointState,
        joints=from_param("joint_names"),
        measured=True,
        doc="sim: the plant's true joints",
    )
    status = Output(Status, doc="driver state and why commands are zeroed (on change)")

    def start(self) -> None:
        table = self.params.table
        try:
            cls = backend_class(self.params.backend)
            self.backend: JointsBackend = cls.from_module(table, self.params, self.context)
        except BackendError as exc:
            raise UserError(f"WOLVERINE_JNTS `{self.name}`: {exc}") from None
        if tuple(self.backend.joint_names) != table.names:
            raise UserError(
                f"WOLVERINE_JNTS `{self.name}`: backend joints {list(self.backend.joint_names)} "
                f"differ from the arm's {list(table.names)}"
            )
        self._zero = np.zeros(table.n)
        self._names = table.names
        self._last_status: tuple[str, str] | None = None
        self._zeroed = 0
        self._started = False
        self.backend.start()
        self._started = True

    def step(self, now: float) -> None:
        if not self._started:
            return
        reading = self.backend.read(now)
        state = JointState(
            names=self._names,
            position=reading.position,
            velocity=reading.velocity,
            gripper=0.0 if np.isnan(reading.gripper) else reading.gripper,
        )
        self.joint_state.send(state)
        if reading.true_position is not None:
            self.true_joint_state.send(replace(state, position=reading.true_position))
        rates, problem = self._command(now)
        accepted = self.backend.command(rates, now)
        gripper = self.gripper_in.get(now)
        if gripper is not None and self.gripper_in.fresh:
            self.backend.command_gripper(gripper.action)
        if not accepted and not problem:
            problem = "backend refused the command"
        if not reading.ok:
            problem = reading.message
        self._report(problem, reading.message)

    def _command(self, now: float) -> tuple[np.ndarray, str]:
        sample = self.rates.get(now)
        if sample is None:
            return self._zero, "no joint rates yet"
        age = self.rates.age(now)
        if age > self.params.max_command_age:
            self._zeroed += 1
            return self._zero, f"joint rates are {age:.3f} s old"
        if tuple(sample.names) != self._names:
            self._zeroed += 1
            return self._zero, f"joint rates for {list(sample.names)}, arm has {list(self._names)}"
        rates = np.asarray(sample.rates, dtype=float)
        if rates.shape != self._zero.shape or not np.all(np.isfinite(rates)):
            self._zeroed += 1
            return self._zero, "joint rates are not finite"
        return rates, ""

    def _report(self, problem: str, message: str) -> None:
        key = (problem, message)
        if key == self._last_status:
            return
        self._last_status = key
        self.status.send(
            Status(
                stage="zero" if problem else "running", message=problem or message, reason=problem
            )
        )

    def stop(self) -> None:
        if getattr(self, "_started", False):
            self.backend.stop()
            self._started = False

    def summary(self) -> dict[str, int]:
        counters = self.backend.counters() if hasattr(self, "backend") else {}
        return {"zeroed_ticks": self._zeroed, **counters}


def _check_canopen_config(path: str, table: DHTable) -> None:
    """ParamProblem unless ``path`` is a CANopen settings file that drives ``table``'s joints
    (what the canopen backend would refuse when the run starts)."""
    from umbra.modules.arm.cia402.backend import order_like_table
    from umbra.modules.arm.cia402.config_yaml import load_canopen_settings

    if not path:
        raise ParamProblem(
            "canopen_config", "is needed by backend canopen (a YAML file of the bus and drives)"
        )
    try:
        order_like_table(load_canopen_settings(path).arm, table, path)
    except (UserError, BackendError) as exc:
        raise ParamProblem("canopen_config", f"cannot be used: {exc}") from None
