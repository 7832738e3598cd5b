"""SafetyMonitor: a flight recorder of the servo side, for judging how the arm stops.

It records, at its rate, the commanded joint rates, the true joint speeds and the true tool
position (forward kinematics of the plant's joint angles). From that record a trial measures,
after any fault, how long the arm took to get zero rate commands and to stand still, and how far
the tool moved meanwhile. It never acts on the arm.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from umbra.connectors import Input, Module, UserError, param
from umbra.connectors.messages import JointRates, JointState
from umbra.modules.arm.arm_params import ArmParams
from umbra.modules.world.trials import STILL_SPEED


class SafetyMonitorParams(ArmParams):
    """Arm (for forward kinematics) and the record's limits."""

    still_speed: float = param(
        STILL_SPEED, "joint speed below which a joint is still", unit="rad/s", gt=0
    )
    max_samples: int = param(20000, "samples kept (oldest dropped)", ge=10, le=10_000_000)

    def required_frames(self) -> list[tuple[str, str]]:
        """The tool point on the flange."""
        return [("flange", "tool")]


class SafetyMonitor(Module[SafetyMonitorParams]):
    """Records rate commands, true joint speeds and the true tool position over time."""

    Params = SafetyMonitorParams

    rates = Input(JointRates, doc="joint-rate commands to the driver")
    true_state = Input(JointState, feedback=True, doc="the plant's TRUE joint state")

    def start(self) -> None:
        try:
            self.T_flange_tool = self.context.frames.lookup("flange", "tool")
        except KeyError as exc:
            raise UserError(
                f"SafetyMonitor `{self.name}` needs the static frame flange->tool: {exc}"
            ) from None
        self._rows: deque[tuple[float, float, float, float, float, float]] = deque(
            maxlen=self.params.max_samples
        )

    def step(self, now: float) -> None:
        state = self.true_state.get(now)
        if state is None:
            return
        rates = self.rates.get(now)
        command = float(np.max(np.abs(rates.rates))) if rates is not None else 0.0
        speed = float(np.max(np.abs(state.velocity))) if np.size(state.velocity) else 0.0
        tool = (self.params.table.fk(state.position) @ self.T_flange_tool)[:3, 3]
        self._rows.append((now, command, speed, float(tool[0]), float(tool[1]), float(tool[2])))

    def record(self) -> np.ndarray:
        """Rows ``[t, max |rate command|, max |joint speed|, x, y, z]`` (s, rad/s, m)."""
        return np.asarray(self._rows, dtype=float).reshape(-1, 6)

    def summary(self) -> dict[str, object]:
        rows = self.record()
        return {
            "samples": len(rows),
            "still_speed": self.params.still_speed,
            "record": [[round(v, 6) for v in row] for row in rows.tolist()],
        }
