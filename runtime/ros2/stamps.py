"""Origins across the border: umbra's run clock (``time.monotonic()``, seconds) and ROS 2's
``header.stamp`` (``CLOCK_REALTIME``, seconds and nanoseconds since the UNIX epoch).

The two clocks are related at the moment of each conversion: the wall clock is read on both sides
of one run-clock reading, the offset is the middle of the two wall readings and its error half
their distance (a few hundred nanoseconds). A stamp from another host carries that host's wall
clock as well, whose disagreement with ours the mapping declares (``clock_error_s``: what NTP or
PTP keep it within). As the links do (``umbra.runtime.links.clock_sync``), an origin coming in is
moved by the whole error bound towards the past, so crossing the border can only make data look
older. A stamp that cannot be related — zero (unset), or later than now by more than the bound —
gives origin ``-inf``, which every guard treats as old; an origin that cannot be dated going out
(``-inf`` or unset) is sent as stamp zero, what ROS 2 tools read as "no time".
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

_NS = 1_000_000_000


@dataclass(frozen=True)
class WallRelation:
    """The wall clock minus the run clock at run time ``run_s`` [s]: ``offset_ns`` [ns], within
    ``error_ns`` [ns]."""

    run_s: float
    offset_ns: int
    error_ns: int


def relate(
    run_clock: Callable[[], float] = time.monotonic,
    wall_clock_ns: Callable[[], int] = time.time_ns,
) -> WallRelation:
    """The relation of the two clocks now (one run-clock reading between two wall readings)."""
    w1 = wall_clock_ns()
    run = run_clock()
    w2 = wall_clock_ns()
    return WallRelation(
        run_s=run, offset_ns=(w1 + w2) // 2 - round(run * _NS), error_ns=(w2 - w1 + 1) // 2
    )


def to_stamp(origin_s: float, rel: WallRelation) -> tuple[int, int]:
    """``(sec, nanosec)`` of a ROS 2 stamp for run-clock time ``origin_s`` [s]; ``(0, 0)`` when
    the origin is unset (0) or cannot be dated (not finite)."""
    if origin_s == 0.0 or not math.isfinite(origin_s):
        return 0, 0
    wall_ns = round(origin_s * _NS) + rel.offset_ns
    if wall_ns <= 0:
        return 0, 0
    return wall_ns // _NS, wall_ns % _NS


@dataclass(frozen=True)
class Dated:
    """A ROS 2 stamp on the run clock: ``stamp_s`` [s] (the instant it names) and ``origin_s``
    [s] (moved towards the past by the error bound; ``-inf`` when it cannot be related)."""

    stamp_s: float
    origin_s: float


def from_stamp(sec: int, nanosec: int, rel: WallRelation, clock_error_s: float) -> Dated:
    """The run-clock reading of a ROS 2 stamp; ``clock_error_s`` [s] bounds the sender's wall
    clock against ours."""
    wall_ns = sec * _NS + nanosec
    if wall_ns <= 0 or nanosec >= _NS:
        return Dated(stamp_s=rel.run_s, origin_s=-math.inf)
    stamp = (wall_ns - rel.offset_ns) / _NS
    bound = rel.error_ns / _NS + clock_error_s
    if stamp > rel.run_s + bound:
        return Dated(stamp_s=rel.run_s, origin_s=-math.inf)  # from the future: cannot be related
    return Dated(stamp_s=stamp, origin_s=stamp - bound)
