"""When a live frame was captured, on the host's monotonic clock [s].

A V4L2 driver stamps each buffer when the sensor delivered it, on ``CLOCK_MONOTONIC`` (the
clock of ``time.monotonic()`` and of the graph's real clock), and OpenCV's V4L2 backend reports
that stamp in milliseconds as ``CAP_PROP_POS_MSEC``. Other backends report something else under
the same name (a file's or a stream's media position, 0 before the first frame), so a driver's
stamp is believed only where it can be a capture time: not after the frame was dequeued and not
longer ago than ``MAX_DRIVER_LAG_S``. Otherwise the frame is as old as the moment ``grab()``
returned it, which is after its exposure and transfer but before its decoding (a stream's
network delay is not seen: its frames look younger than they are by that much).
"""

from __future__ import annotations

import math

#: The oldest a driver's stamp may be when its frame is dequeued [s]; past it the stamp is not
#: on our clock (a media position, or another clock).
MAX_DRIVER_LAG_S = 1.0
#: How far a driver's stamp may lie after the dequeue [s] (clock granularity).
DRIVER_LEAD_TOLERANCE_S = 0.002


def capture_time(driver_ms: float | None, grabbed_s: float) -> tuple[float, str]:
    """The capture time [s, monotonic] of a frame dequeued at ``grabbed_s`` whose backend
    reported ``driver_ms`` [ms] (None: not asked), and which of the two it is: ``"driver"`` or
    ``"grab"``."""
    if driver_ms is not None and math.isfinite(driver_ms) and driver_ms > 0:
        driver_s = driver_ms / 1000.0
        if grabbed_s - MAX_DRIVER_LAG_S <= driver_s <= grabbed_s + DRIVER_LEAD_TOLERANCE_S:
            return min(driver_s, grabbed_s), "driver"
    return grabbed_s, "grab"
