"""How the named figures of a :class:`~umbra.connectors.messages.Status` read to a person.

A grab's state (:class:`~umbra.connectors.states.ServoState`) carries its errors in ``values``:
``error_x``, ``error_y``, ``error_z`` [m] and ``error_roll`` [rad]; its producer (vsServo) and
the displays that take any status (the video overlay) write them the same way, from here.
"""

from __future__ import annotations

import math


def error_figure(name: str, value: float) -> str:
    """``error_x`` [m] -> ``x +1.2 mm``; ``error_roll`` [rad] -> ``roll -0.40 deg``; any other
    value by its name and four significant digits."""
    short = name.removeprefix("error_")
    if name == "error_roll":
        return f"{short} {math.degrees(value):+.2f} deg"
    if name.startswith("error_"):
        return f"{short} {value * 1e3:+.1f} mm"
    return f"{short} {value:.4g}"
