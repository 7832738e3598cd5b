"""Conformance: the focus and memory commands a PTZ panel sends, driven by pyvisca (an independent
VISCA library from PyPI) through a real pty into the simulated FCB camera: pyvisca's own
``focus_far``/``focus_near``/``focus_stop``/``autofocus``/``preset_set``/``preset_recall`` and its
raw ``comm``/``inq`` for manual focus, focus direct, memory reset and the two inquiries, with the
replies the FCB command list gives (ACK ``90 4z FF``, completion ``90 5z FF``, not executable
``90 6z 41 FF``)."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from tests.poll import wait_for
from tests.visca.pyvisca_wire import inquire, replies
from umbra.modules.calib.visca import protocol as vp
from umbra.modules.calib.visca.sim_camera import SimFcbCamera
from umbra.modules.calib.visca.sim_lens import FOCUS_RAW_FAR, FOCUS_RAW_NEAR
from umbra.modules.calib.visca.zoom_motion import ZoomSpeeds

pyvisca = pytest.importorskip("pyvisca.visca", reason="pyvisca is in the [test] extra")

pytestmark = pytest.mark.timeout(60)

AF_RAW = 0x3000
"""Focus position where the simulated scene is sharp (the simulator's default)."""
DONE = ["9041ff", "9051ff"]
"""ACK in socket 1, then its completion."""


@pytest.fixture
def camera() -> Iterator[SimFcbCamera]:
    # zoom direct and the fastest focus: 1 s over each range; the slowest focus speed 8 s
    with SimFcbCamera(speeds=ZoomSpeeds(direct_s=1.0)) as sim:
        yield sim


@pytest.fixture
def ptz(camera: SimFcbCamera) -> Iterator[object]:
    driver = pyvisca.PTZ(output=camera.path)
    yield driver
    driver.close()


def focus_position(ptz: object) -> int:
    """CAM_FocusPosInq ``81 09 04 48 FF`` -> ``90 50 0p 0q 0r 0s FF``."""
    return vp.from_nibbles(inquire(ptz, "81090448FF"))


def wait_for_auto_focus(ptz: object) -> None:
    """Until the focus reports the simulated lens's sharp position (``AF_RAW``)."""
    wait_for(
        lambda: focus_position(ptz),
        5.0,
        "the auto focus position",
        interval_s=0,
        ok=lambda p: p == AF_RAW,
    )


def focus_mode(ptz: object) -> str:
    """CAM_FocusModeInq ``81 09 04 38 FF`` -> ``90 50 02 FF`` (auto) / ``03`` (manual)."""
    return {b"\x02": "auto", b"\x03": "manual"}[inquire(ptz, "81090438FF")]


def test_focus_far_near_stop_and_auto(camera: SimFcbCamera, ptz: object) -> None:
    assert focus_mode(ptz) == "auto" and focus_position(ptz) == AF_RAW  # power-on state
    ptz.focus_far(7)  # 81 01 04 08 27 FF: manual focus control during auto focus
    assert replies(ptz, 1) == ["906141ff"]  # not executable (socket 1)
    ptz.comm("8101043803FF")  # manual focus
    assert replies(ptz, 2) == DONE
    assert focus_mode(ptz) == "manual"

    ptz.focus_near(7)  # 81 01 04 08 37 FF: completes at once, the focus moves on
    assert replies(ptz, 2) == DONE
    moving = wait_for(
        lambda: focus_position(ptz),
        5.0,
        "the focus moving near",
        interval_s=0,
        ok=lambda p: p > AF_RAW + 0x2000,
    )
    assert AF_RAW + 0x2000 < moving < FOCUS_RAW_NEAR
    ptz.focus_stop()  # 81 01 04 08 00 FF
    assert replies(ptz, 2) == DONE
    near = focus_position(ptz)
    assert near >= moving and near == camera.focus_raw()
    assert focus_position(ptz) == near  # stopped: the same answer twice

    ptz.focus_far(0)  # the slowest speed: 8 s over the range
    assert replies(ptz, 2) == DONE
    wait_for(
        lambda: focus_position(ptz),
        5.0,
        "the focus moving far",
        interval_s=0,
        ok=lambda p: p < near - 0x800,
    )
    ptz.focus_stop()
    assert replies(ptz, 2) == DONE
    far = focus_position(ptz)
    assert FOCUS_RAW_FAR < far < near - 0x800

    ptz.autofocus()  # 81 01 04 38 02 FF: the auto focus runs to the sharp position
    assert replies(ptz, 2) == DONE
    assert focus_mode(ptz) == "auto" and camera.focus_auto()
    wait_for_auto_focus(ptz)


def test_focus_direct_holds_its_socket_until_arrival(camera: SimFcbCamera, ptz: object) -> None:
    ptz.comm("8101043810FF")  # auto/manual toggle: auto -> manual
    assert replies(ptz, 2) == DONE
    assert focus_mode(ptz) == "manual"
    ptz.comm("810104480E000000FF")  # focus direct 0xE000 (0.8 s away at the direct speed)
    assert replies(ptz, 1) == ["9041ff"]
    assert focus_position(ptz) < 0xE000  # still on its way
    assert replies(ptz, 1) == ["9051ff"]  # completion on arrival
    assert focus_position(ptz) == 0xE000
    ptz.comm("8101041801FF")  # one-push AF trigger in manual focus: focuses once
    assert replies(ptz, 2) == DONE
    wait_for_auto_focus(ptz)
    assert focus_mode(ptz) == "manual"


def test_memory_set_move_recall_restores_zoom_and_focus(camera: SimFcbCamera, ptz: object) -> None:
    ptz.set_zoom(0x0800)
    assert replies(ptz, 2) == DONE
    ptz.comm("8101043803FF")
    assert replies(ptz, 2) == DONE
    ptz.comm("8101044808000000FF")  # focus direct 0x8000
    assert replies(ptz, 2) == DONE
    ptz.preset_set(2)  # 81 01 04 3F 01 02 FF
    assert replies(ptz, 2) == DONE

    ptz.set_zoom(0x4000)
    assert replies(ptz, 2) == DONE
    ptz.comm("8101044802000000FF")  # focus direct 0x2000
    assert replies(ptz, 2) == DONE
    ptz.autofocus()
    assert replies(ptz, 2) == DONE
    assert ptz.get_zoom() == 0x4000 and focus_mode(ptz) == "auto"

    ptz.preset_recall(2)  # 81 01 04 3F 02 02 FF: completes when zoom and focus arrived
    assert replies(ptz, 1) == ["9041ff"]
    assert 0x0800 < ptz.get_zoom() < 0x4000  # on its way back (0.9 s)
    assert replies(ptz, 1) == ["9051ff"]
    assert ptz.get_zoom() == 0x0800 == camera.position_raw()
    assert focus_position(ptz) == 0x8000 and focus_mode(ptz) == "manual"

    ptz.comm("8101043F0002FF")  # memory reset: back to the power-on state
    assert replies(ptz, 2) == DONE
    ptz.preset_recall(2)
    assert replies(ptz, 2) == DONE
    assert ptz.get_zoom() == 0 and focus_mode(ptz) == "auto"
    wait_for_auto_focus(ptz)


def test_a_new_zoom_cancels_a_running_recall(camera: SimFcbCamera, ptz: object) -> None:
    ptz.set_zoom(0x4000)
    assert replies(ptz, 2) == DONE
    ptz.preset_recall(0)  # never set: the power-on state, zoom back to 0 (1 s)
    assert replies(ptz, 1) == ["9041ff"]
    ptz.zoom_stop()  # takes socket 2 and ends the recall running in socket 1
    assert replies(ptz, 3) == ["9042ff", "906104ff", "9052ff"]
    stopped = ptz.get_zoom()
    assert 0 < stopped < 0x4000 and ptz.get_zoom() == stopped
