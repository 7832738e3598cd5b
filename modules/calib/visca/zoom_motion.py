"""How the simulated FCB lens moves: constant-rate travel toward a target, at the speed of the
command that started it.

Speeds are wide-to-tele travel times over the optical range (raw 0 .. 0x4000). Zoom direct runs at
the fastest speed, ``full_range_s``. The variable speeds ``p`` = 0..7 of ``8x 01 04 07 2p/3p FF``
take ``full_range_s * 8 / (p + 1)`` (p = 7 as fast as zoom direct, p = 0 eight times slower), and
the standard-speed tele/wide (``02``/``03``) runs at p = ``STANDARD_SPEED``. These are model
figures, not a Sony table: this project found no published per-speed travel times for an FCB
model, so the shape (speed proportional to p + 1) and the 2.4 s top speed are stated
assumptions. A real camera's figures go in :class:`ZoomSpeeds` (``travel_s`` per speed).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from umbra.modules.calib.visca.commands import MAX_ZOOM_SPEED

STANDARD_SPEED = 3
"""Variable speed that the standard-speed tele/wide commands (``02``/``03``) move at (model)."""


def _model_travel(full_range_s: float) -> tuple[float, ...]:
    return tuple(full_range_s * (MAX_ZOOM_SPEED + 1) / (p + 1) for p in range(MAX_ZOOM_SPEED + 1))


@dataclass(frozen=True)
class ZoomSpeeds:
    """Wide-to-tele travel times [s]: ``direct_s`` for zoom direct, ``travel_s[p]`` for the
    variable speeds p = 0..7, ``standard`` the p used by the standard-speed commands."""

    direct_s: float = 2.4
    travel_s: tuple[float, ...] = field(default=())
    standard: int = STANDARD_SPEED

    def __post_init__(self) -> None:
        if not self.direct_s > 0:
            raise ValueError(f"zoom direct travel time must be > 0 s, got {self.direct_s}")
        if not self.travel_s:
            object.__setattr__(self, "travel_s", _model_travel(self.direct_s))
        if len(self.travel_s) != MAX_ZOOM_SPEED + 1 or not all(t > 0 for t in self.travel_s):
            raise ValueError(f"expected 8 positive travel times (p = 0..7), got {self.travel_s}")
        if not 0 <= self.standard <= MAX_ZOOM_SPEED:
            raise ValueError(f"standard speed must be 0..7, got {self.standard}")

    def seconds(self, speed: int | None) -> float:
        """Wide-to-tele time at variable speed ``speed`` (None: the standard speed)."""
        return self.travel_s[self.standard if speed is None else speed]


@dataclass(frozen=True)
class Motion:
    """Zoom travel at a constant rate [raw/s] from ``start_raw`` at time ``t0`` [s] (monotonic)
    to ``target_raw``, where it stops."""

    start_raw: int
    target_raw: int
    t0: float
    rate: float

    def position(self, now: float) -> int:
        span = self.target_raw - self.start_raw
        travelled = self.rate * max(0.0, now - self.t0)
        if travelled >= abs(span):
            return self.target_raw
        return self.start_raw + round(travelled if span > 0 else -travelled)

    def arrival(self) -> float:
        return self.t0 + abs(self.target_raw - self.start_raw) / self.rate

    def moving(self, now: float) -> bool:
        return now < self.arrival()

    def stopped(self, now: float) -> Motion:
        """The lens held where it is at ``now``."""
        here = self.position(now)
        return Motion(here, here, now, self.rate)
