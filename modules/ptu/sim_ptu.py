"""A simulated pan-tilt unit: each axis slews to its target with rate and acceleration limits.

Per axis a time-optimal trapezoidal profile is re-evaluated each step (a discrete bang-bang law
on the braking distance), so a new target may arrive at any time. Radians, seconds.
"""

from __future__ import annotations

import numpy as np

from umbra.modules.ptu.ptu_model import PtuGeometry


class SimPtu:
    """Pan and tilt angles, their rates, and targets of a simulated unit."""

    def __init__(self, geometry: PtuGeometry, pan: float = 0.0, tilt: float = 0.0) -> None:
        geometry.check(pan, tilt)
        self.geometry = geometry
        self.angles = np.array([pan, tilt], dtype=float)
        self.rates = np.zeros(2)
        self.targets = self.angles.copy()

    def command(self, pan: float, tilt: float) -> None:
        """Set new targets (rad); raises PtuLimitError outside the travel."""
        self.geometry.check(pan, tilt)
        self.targets = np.array([pan, tilt], dtype=float)

    @property
    def moving(self) -> bool:
        return bool(np.any(np.abs(self.rates) > 1e-9) or np.any(self.targets != self.angles))

    def step(self, dt: float) -> None:
        """Advance ``dt`` seconds."""
        g = self.geometry
        for i in range(2):
            error = self.targets[i] - self.angles[i]
            v = self.rates[i]
            if abs(error) < 1e-9 and abs(v) < g.max_accel * dt:
                self.angles[i], self.rates[i] = self.targets[i], 0.0
                continue
            # the largest speed from which the discrete law still brakes to rest at the target
            a_dt = g.max_accel * dt
            reachable = a_dt * (np.sqrt(0.25 + 2.0 * abs(error) / (a_dt * dt)) - 0.5)
            v_stop = np.sign(error) * min(g.max_rate, reachable)
            v_new = v + np.clip(v_stop - v, -a_dt, a_dt)
            step = v_new * dt
            if abs(step) >= abs(error) and abs(v_new) <= a_dt + 1e-12:
                self.angles[i], self.rates[i] = self.targets[i], 0.0
            else:
                self.angles[i] += step
                self.rates[i] = v_new
