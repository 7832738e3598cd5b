"""What the page draws, as plain JSON-ready dicts built from the graph's messages. Pure.

Units on the page: millimetres and degrees (converted here, once); pixels for the overlay.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from umbra.connectors.messages import Contour, JointState
from umbra.connectors.states import GuardState, ServoReason, ServoStage, ServoState
from umbra.modules.vision.features import polygon_features
from umbra.modules.vision.sanity import SanityLimits, bounding_shapes

#: servo error names -> (label, scale to page units, unit)
ERRORS = {
    "error_x": ("x", 1000.0, "mm"),
    "error_y": ("y", 1000.0, "mm"),
    "error_z": ("z", 1000.0, "mm"),
    "error_roll": ("roll", 180.0 / math.pi, "deg"),
}

#: servo stages in which vsServo itself commands zero, and the banner text
_SERVO_ZERO = {
    ServoStage.ASSIST: "vsServo asks for the operator",
    ServoStage.PAUSED: "paused by the operator",
    ServoStage.ABORTED: "grab aborted",
    ServoStage.DONE: "grab complete",
}


def _r(x: float, nd: int = 1) -> float:
    return round(float(x), nd)


def overlay(contour: Contour | None, limits: SanityLimits) -> dict[str, Any] | None:
    """The snake overlay in image pixels: polygon, flagged vertices, outer rectangle, inner
    ellipse, centroid and principal axis (None when there is nothing to draw)."""
    if contour is None:
        return None
    vertices = np.asarray(contour.vertices, dtype=float).reshape(-1, 2)
    if len(vertices) < 3 or not np.all(np.isfinite(vertices)):
        return None
    out: dict[str, Any] = {
        "status": contour.status,
        "reason": contour.reason,
        "points": [[_r(u), _r(v)] for u, v in vertices],
        "offending": [
            int(i) for i in np.asarray(contour.offending).ravel() if 0 <= i < len(vertices)
        ],
    }
    try:
        features = polygon_features(vertices)
    except ValueError:
        return out
    rectangle, ellipse = bounding_shapes(features, limits)
    cu, cv = features.centroid_uv
    angle = features.orientation_rad
    half = rectangle.half_sizes[0] / (1.0 + limits.rectangle_margin)
    du, dv = half * math.cos(angle), half * math.sin(angle)
    out.update(
        rectangle=[[_r(u), _r(v)] for u, v in rectangle.corners()],
        ellipse={
            "cx": _r(ellipse.center_uv[0]),
            "cy": _r(ellipse.center_uv[1]),
            "rx": _r(ellipse.half_sizes[0]),
            "ry": _r(ellipse.half_sizes[1]),
            "angle_deg": _r(math.degrees(ellipse.angle_rad), 2),
        },
        centroid=[_r(cu), _r(cv)],
        axis=[[_r(cu - du), _r(cv - dv)], [_r(cu + du), _r(cv + dv)]],
    )
    return out


def servo_view(status: ServoState | None) -> dict[str, Any]:
    """Stage, message, reason and the four errors in mm / deg."""
    if status is None:
        return {"stage": "-", "message": "no status from vsServo yet", "assist": False}
    errors = {
        label: _r(status.values[name] * scale, 2)
        for name, (label, scale, _unit) in ERRORS.items()
        if name in status.values and math.isfinite(status.values[name])
    }
    return {
        "stage": status.stage,
        "message": status.message,
        "assist": bool(status.assist),
        "reason": status.reason,
        "errors": errors,
    }


def error_rows(rows: Any) -> list[list[float | None]]:
    """Servo error rows ``[t s, x m, y m, z m, roll rad]`` in page units ``[t s, x mm, y mm,
    z mm, roll deg]`` (None where an error was not measured)."""
    scales = [scale for _label, scale, _unit in ERRORS.values()]
    return [
        [
            row[0],
            *[
                round(x * k, 3) if math.isfinite(x) else None
                for x, k in zip(row[1:], scales, strict=True)
            ],
        ]
        for row in rows
    ]


def zero_banner(servo: ServoState | None, guard: GuardState | None) -> str:
    """Why the servo side commands zero now ("" when it is passing a command), in the
    producers' exact words."""
    if guard is not None and not guard.passing:
        return f"servo side at zero (REG_VEL): {guard.reason}"
    if guard is not None and guard.jog:
        return ""  # the operator is jogging by hand: REG_VEL passes the jog
    if servo is not None and servo.stage in _SERVO_ZERO:
        why = _SERVO_ZERO[servo.stage]
        detail = f": {servo.reason}" if servo.reason and servo.stage == ServoStage.ASSIST else ""
        return f"servo side at zero: {why}{detail}"
    if servo is not None and servo.stage == ServoStage.ACQUIRE and servo.code != ServoReason.NONE:
        return f"servo side at zero: {servo.message}"  # e.g. waiting: snake has no contour
    return ""


def joints_view(
    state: JointState | None, q_min: np.ndarray, q_max: np.ndarray, qd_max: np.ndarray
) -> list[dict[str, Any]]:
    """Joint positions and rates [deg, deg/s] with their limits and the fraction used."""
    if state is None:
        return []
    q = np.asarray(state.position, dtype=float)
    qd = np.asarray(state.velocity, dtype=float) if len(state.velocity) else np.zeros_like(q)
    rows = []
    for i, name in enumerate(state.names):
        if i >= len(q_min):
            break
        lo, hi = q_min[i], q_max[i]
        span = max(hi - lo, 1e-9)
        rows.append(
            {
                "name": name,
                "q_deg": _r(math.degrees(q[i]), 2),
                "min_deg": _r(math.degrees(lo)),
                "max_deg": _r(math.degrees(hi)),
                "q_frac": _r((q[i] - lo) / span, 3),
                "qd_deg_s": _r(math.degrees(qd[i]) if i < len(qd) else 0.0, 2),
                "qd_max_deg_s": _r(math.degrees(qd_max[i])),
                "qd_frac": _r(abs(qd[i]) / max(qd_max[i], 1e-9) if i < len(qd) else 0.0, 3),
            }
        )
    return rows


def link_view(name: str, age: float, alive: bool, origin_age: float = math.inf) -> dict[str, Any]:
    """One input: its age [ms] from its producer's stamp, the age of the sensor data behind it
    [ms] (None: nothing yet), and whether its producer is alive."""
    return {
        "name": name,
        "age_ms": None if not math.isfinite(age) else _r(age * 1e3),
        "origin_ms": None if not math.isfinite(origin_age) else _r(origin_age * 1e3),
        "alive": alive,
    }
