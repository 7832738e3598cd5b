"""The simulated drive's velocity loop: ramps and the quick stop option codes (CiA 402).

Drive units: counts/s, counts/s^2, seconds.
"""

from __future__ import annotations

from umbra.modules.arm.cia402 import objects as obj

#: Quick stop option code (0x605A) -> the deceleration object it brakes with (None: at once).
#: 3 / 7 (current limit) and 4 / 8 (voltage limit): the simulation has no motor model, it
#: brakes at max deceleration (0x60C6).
QUICK_STOP_DECELERATION: dict[int, int | None] = {
    0: None,
    1: obj.PROFILE_DECELERATION,
    2: obj.QUICK_STOP_DECELERATION,
    3: obj.MAX_DECELERATION,
    4: obj.MAX_DECELERATION,
    5: obj.PROFILE_DECELERATION,
    6: obj.QUICK_STOP_DECELERATION,
    7: obj.MAX_DECELERATION,
    8: obj.MAX_DECELERATION,
}
#: Option codes after which a stopped drive goes on to Switch on disabled (5..8 stay).
QUICK_STOP_TO_DISABLED = frozenset({0, 1, 2, 3, 4})


def ramp(v0: float, target: float, limit: float, dt_s: float) -> tuple[float, float]:
    """Velocity after ``dt_s`` seconds slewing from ``v0`` towards ``target`` at ``limit``
    (counts/s^2; <= 0: at once), and the travel (counts) over those seconds, exact also when
    the ramp ends within the step (a long step after a stopped process)."""
    step = limit * dt_s
    if limit <= 0 or abs(target - v0) <= step:
        ramp_s = 0.0 if limit <= 0 else abs(target - v0) / limit
        return float(target), 0.5 * (v0 + target) * ramp_s + target * (dt_s - ramp_s)
    v1 = v0 + step if target > v0 else v0 - step
    return v1, 0.5 * (v0 + v1) * dt_s
