"""How servo errors read to a person: one short figure per error, in mm and degrees."""

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
