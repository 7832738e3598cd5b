"""What the /sketch page says of each camera's pan/tilt unit and zoom, as plain JSON (pure).

The operator sees whether the cameras are still (a snapshot waits for them to stop and settle)
and where they point, from the devices' own reports: a PTU's ``PtuState`` and a zoom camera's
``ZoomState``. A device that has not reported for ``silent_s`` is said to be silent, not still:
the page never shows an old report as the present.
"""

from __future__ import annotations

import math
from typing import Any

from umbra.connectors.messages import ZoomState
from umbra.connectors.ptu_messages import PtuState


def camera_view(
    side: str,
    ptu: PtuState | None,
    ptu_age_s: float,
    zoom: ZoomState | None,
    zoom_age_s: float,
    silent_s: float,
) -> dict[str, Any]:
    """Camera ``side``'s devices as the page shows them: ``ptu`` (``moving``, ``pan_deg``,
    ``tilt_deg`` to 0.1 deg, ``ok``, ``status``, ``silent``) and ``zoom`` (``zoom`` 0 wide .. 1
    tele to 0.01, ``moving``, ``ok``, ``status``, ``silent``; ``ok``: nothing is wrong with it,
    else ``status`` says what), each None when the graph wires none or nothing
    came yet; ``still``: every device known reported, recently, that it is not moving. Ages
    [s] are since each report was received; ``silent_s`` [s] (> 0) the longest that is
    recent."""
    view: dict[str, Any] = {"side": side, "ptu": None, "zoom": None}
    if ptu is not None:
        view["ptu"] = {
            "moving": bool(ptu.moving),
            "pan_deg": round(math.degrees(ptu.pan), 1),
            "tilt_deg": round(math.degrees(ptu.tilt), 1),
            "ok": ptu.ok,
            "status": ptu.status,
            "silent": not ptu_age_s <= silent_s,
        }
    if zoom is not None:
        view["zoom"] = {
            "zoom": round(float(zoom.zoom), 2),
            "moving": bool(zoom.moving),
            "ok": zoom.ok,
            "status": zoom.status,
            "silent": not zoom_age_s <= silent_s,
        }
    devices = [d for d in (view["ptu"], view["zoom"]) if d is not None]
    view["still"] = bool(devices) and not any(d["moving"] or d["silent"] for d in devices)
    return view
