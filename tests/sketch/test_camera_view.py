"""The /sketch page's line on each camera's PTU and zoom (pure)."""

from __future__ import annotations

import math

from umbra.connectors.messages import ZoomState
from umbra.connectors.ptu_messages import PtuState
from umbra.modules.sketch_page.camera_view import camera_view


def test_still_only_when_every_device_reported_recently_that_it_is_not_moving() -> None:
    ptu = PtuState(pan=math.radians(12.34), tilt=math.radians(-4.06), moving=False)
    zoom = ZoomState(zoom=0.298, moving=False)
    view = camera_view("a", ptu, 0.02, zoom, 0.1, silent_s=1.0)
    assert view["ptu"] == {
        "moving": False,
        "pan_deg": 12.3,
        "tilt_deg": -4.1,
        "ok": True,
        "status": "ok",
        "silent": False,
    }
    assert view["zoom"] == {
        "zoom": 0.3,
        "moving": False,
        "ok": True,
        "status": "ok",
        "silent": False,
    }
    assert view["still"] is True
    # slewing, zooming, silent (an age past the bound, or none at all), or nothing known
    assert not camera_view("a", PtuState(pan=0, tilt=0, moving=True), 0.0, zoom, 0.0, 1.0)["still"]
    zooming = ZoomState(zoom=0.5, moving=True)
    assert not camera_view("a", ptu, 0.0, zooming, 0.0, 1.0)["still"]
    old = camera_view("a", ptu, 1.5, zoom, 0.0, 1.0)
    assert old["ptu"]["silent"] and not old["still"]
    assert camera_view("a", ptu, math.inf, None, math.inf, 1.0)["ptu"]["silent"]
    assert camera_view("a", ptu, math.nan, None, math.inf, 1.0)["ptu"]["silent"]
    nothing = camera_view("b", None, math.inf, None, math.inf, 1.0)
    assert nothing == {"side": "b", "ptu": None, "zoom": None, "still": False}
    # a PTU alone (no zoom camera wired) can be still
    assert camera_view("a", ptu, 0.0, None, math.inf, 1.0)["still"]


def test_a_device_that_says_what_is_wrong_is_not_ok_and_its_words_are_kept() -> None:
    """The page decides on ``ok`` (the devices' one ``DEVICE_OK``) and shows the words."""
    refused = PtuState(pan=0.0, tilt=0.0, status="refused: tilt beyond its limit")
    lost = ZoomState(zoom=0.0, status="no_reply: the camera did not answer 3 times")
    view = camera_view("a", refused, 0.0, lost, 0.0, silent_s=1.0)
    assert view["ptu"]["ok"] is False and view["ptu"]["status"] == refused.status
    assert view["zoom"]["ok"] is False and view["zoom"]["status"] == lost.status
    assert camera_view("a", PtuState(pan=0.0, tilt=0.0), 0.0, None, 0.0, 1.0)["ptu"]["ok"]
