"""Conformance: pyvisca (an independent VISCA library from PyPI) drives the simulated FCB camera
over a real pty, with its own command encoders where it has them (zoom in/out/stop at variable
speeds, zoom direct, zoom position, power and power inquiry, its IF_Clear-based ``cancel``) and
its raw ``comm``/``inq`` for the rest (address set, standard-speed zoom, version, socket cancel).
"""

from __future__ import annotations

import time
from collections.abc import Iterator

import pytest

from tests.poll import wait_for
from tests.visca.pyvisca_wire import replies
from umbra.modules.calib.visca.sim_camera import SimFcbCamera
from umbra.modules.calib.visca.zoom_motion import ZoomSpeeds

pyvisca = pytest.importorskip("pyvisca.visca", reason="pyvisca is in the [test] extra")

pytestmark = pytest.mark.timeout(60)


@pytest.fixture
def camera() -> Iterator[SimFcbCamera]:
    with SimFcbCamera(speeds=ZoomSpeeds(direct_s=2.0), power_on_s=0.3) as sim:
        yield sim


@pytest.fixture
def ptz(camera: SimFcbCamera) -> Iterator[object]:
    driver = pyvisca.PTZ(output=camera.path)  # pyserial, 9600 8N1, as on a real FCB cable
    yield driver
    driver.close()


def test_address_set_and_if_clear(ptz: object) -> None:
    ptz.command("883001FF")
    assert replies(ptz, 1) == ["883002ff"]
    ptz.command("88010001FF")
    assert replies(ptz, 1) == ["88010001ff"]
    ptz.cancel()  # pyvisca's cancel is the addressed IF_Clear 81 01 00 01 FF
    assert replies(ptz, 1) == ["9050ff"]


def test_zoom_direct_and_position_inquiry(camera: SimFcbCamera, ptz: object) -> None:
    ptz.set_zoom(0x2000)
    assert replies(ptz, 2) == ["9041ff", "9051ff"]  # ACK, completion on arrival (1 s)
    assert camera.position_raw() == 0x2000
    assert ptz.get_zoom() == 0x2000


def test_zoom_in_out_stop_at_variable_speeds(camera: SimFcbCamera, ptz: object) -> None:
    """Fastest (2 s for the range) then slowest (16 s) for about 0.3 s each: the slow one moves
    about 8 times less (bounds wide enough for a loaded machine's timing)."""
    ptz.zoom_in(7)  # 81 01 04 07 27 FF
    assert replies(ptz, 2) == ["9041ff", "9051ff"]
    time.sleep(0.3)
    ptz.zoom_stop()
    assert replies(ptz, 2) == ["9041ff", "9051ff"]
    fast = ptz.get_zoom()
    assert 0x4000 * 0.2 / 2.0 < fast < 0x4000 * 0.9 / 2.0
    assert ptz.get_zoom() == fast  # stopped
    ptz.zoom_out(0)  # 81 01 04 07 30 FF
    assert replies(ptz, 2) == ["9041ff", "9051ff"]
    time.sleep(0.3)
    ptz.zoom_stop()
    assert replies(ptz, 2) == ["9041ff", "9051ff"]
    slow = fast - ptz.get_zoom()
    assert 0x4000 * 0.2 / 16.0 < slow < 0x4000 * 0.9 / 16.0
    assert fast / slow > 2.5  # 8 x in the model


def test_standard_speed_tele_and_wide_with_raw_packets(camera: SimFcbCamera, ptz: object) -> None:
    ptz.comm("8101040702FF")  # CAM_Zoom Tele (standard)
    assert replies(ptz, 2) == ["9041ff", "9051ff"]
    wait_for(lambda: camera.position_raw() > 0, 5.0, "the lens under way to tele")
    ptz.comm("8101040700FF")
    assert replies(ptz, 2) == ["9041ff", "9051ff"]
    tele = ptz.get_zoom()
    assert tele > 0
    ptz.comm("8101040703FF")  # CAM_Zoom Wide (standard)
    assert replies(ptz, 2) == ["9041ff", "9051ff"]
    wait_for(lambda: camera.position_raw() < tele, 5.0, "the lens under way to wide")
    ptz.zoom_stop()
    assert replies(ptz, 2) == ["9041ff", "9051ff"]
    assert ptz.get_zoom() < tele


def test_power_off_on_and_power_inquiry(camera: SimFcbCamera, ptz: object) -> None:
    assert ptz.get_power() == 1
    ptz.power(0)
    assert replies(ptz, 2) == ["9041ff", "9051ff"]
    assert ptz.get_power() == 0
    ptz.zoom_in(5)
    assert replies(ptz, 1) == ["906141ff"]  # command not executable in standby
    ptz.power(1)
    assert replies(ptz, 2, timeout_s=3.0) == ["9041ff", "9051ff"]  # completion after start-up
    assert ptz.get_power() == 1
    ptz.zoom_in(5)
    assert replies(ptz, 2) == ["9041ff", "9051ff"]


def test_version_inquiry_and_socket_cancel(ptz: object) -> None:
    version = ptz.inq("81090002FF")
    assert version.startswith("90500020") and version.endswith("02ff") and len(version) == 20
    ptz.set_zoom(0x4000)
    assert replies(ptz, 1) == ["9041ff"]
    ptz.comm("8121FF")  # cancel socket 1
    assert replies(ptz, 1) == ["906104ff"]
    ptz.comm("8122FF")
    assert replies(ptz, 1) == ["906205ff"]
    ptz.comm("8101043302FF")  # backlight on, a command the simulator does not have: syntax error
    assert replies(ptz, 1) == ["906002ff"]
