"""The simulated FCB camera answers the rest of the FCB command set over a real pty: zoom
tele/wide/stop at standard and variable speeds, power and its inquiry, version, cancel, and the
error replies (cancelled, no socket, buffer full, not executable) with their socket numbers."""

from __future__ import annotations

import time

import pytest
import serial

from tests.poll import wait_for
from tests.visca.raw_wire import h, position, read_packet
from umbra.modules.calib.visca import commands as vc
from umbra.modules.calib.visca import protocol as vp
from umbra.modules.calib.visca.sim_camera import SimFcbCamera
from umbra.modules.calib.visca.zoom_motion import ZoomSpeeds


def test_standard_tele_acks_completes_at_once_and_moves_until_stop(
    sim: SimFcbCamera, wire: serial.Serial
) -> None:
    wire.write(h("81 01 04 07 02 FF"))
    assert read_packet(wire) == h("90 41 FF")
    assert read_packet(wire) == h("90 51 FF")  # completes at once; the lens moves on
    wait_for(lambda: sim.position_raw() > 0, 5.0, "the lens under way")
    assert sim.moving() and sim.target_raw() == 0x4000
    wire.write(h("81 01 04 07 00 FF"))
    assert read_packet(wire) == h("90 41 FF")  # the socket was freed by the completion
    assert read_packet(wire) == h("90 51 FF")
    stopped = sim.position_raw()
    assert 0 < stopped < 0x4000 and not sim.moving()
    time.sleep(0.2)  # a window: the lens stays where it stopped
    assert position(wire) == stopped == sim.position_raw()
    wire.write(h("81 01 04 07 03 FF"))  # standard wide back to the wide end
    assert read_packet(wire) == h("90 41 FF") and read_packet(wire) == h("90 51 FF")
    assert sim.target_raw() == 0


@pytest.mark.parametrize("speed", [0, 3, 7])
def test_variable_speed_tele_moves_at_the_modelled_rate(speed: int) -> None:
    """The zoom rate between two position inquiries 0.5 s apart is the modelled one (within 25 %:
    each inquiry's instant is known to the time its reply takes on a loaded machine)."""
    speeds = ZoomSpeeds(direct_s=2.0)
    rate = 0x4000 / speeds.seconds(speed)  # raw/s: 16 s, 4 s, 2 s wide to tele
    with SimFcbCamera(speeds=speeds) as camera, serial.Serial(camera.path, timeout=2) as port:
        port.write(vc.encode_zoom_move(1, vc.ZoomDirection.TELE, speed))
        assert read_packet(port) == h("90 41 FF") and read_packet(port) == h("90 51 FF")
        wait_for(lambda: camera.position_raw() > 0, 5.0, "the lens under way")
        first, t1 = position(port), time.monotonic()
        time.sleep(0.5)  # the span the rate is measured over
        second, t2 = position(port), time.monotonic()
        assert 0 < first < second < 0x4000
        assert (second - first) / (t2 - t1) == pytest.approx(rate, rel=0.25)
        port.write(vc.encode_zoom_stop(1))
        assert read_packet(port) == h("90 41 FF") and read_packet(port) == h("90 51 FF")


def test_speeds_scale_as_modelled() -> None:
    speeds = ZoomSpeeds(direct_s=2.4)
    assert [round(speeds.seconds(p), 2) for p in range(8)] == [
        19.2,
        9.6,
        6.4,
        4.8,
        3.84,
        3.2,
        2.74,
        2.4,
    ]
    assert speeds.seconds(None) == speeds.seconds(3)
    with pytest.raises(ValueError, match="8 positive"):
        ZoomSpeeds(travel_s=(1.0, 2.0))


def test_power_off_refuses_lens_commands_until_power_on_completes(wire: serial.Serial) -> None:
    wire.write(h("81 09 04 00 FF"))
    assert read_packet(wire) == h("90 50 02 FF")  # on
    wire.write(h("81 01 04 00 03 FF"))
    assert read_packet(wire) == h("90 41 FF") and read_packet(wire) == h("90 51 FF")
    wire.write(h("81 09 04 00 FF"))
    assert read_packet(wire) == h("90 50 03 FF")  # standby
    wire.write(h("81 01 04 07 02 FF"))
    assert read_packet(wire) == h("90 61 41 FF")  # not executable, in the socket it would take
    wire.write(h("81 09 04 47 FF"))
    assert read_packet(wire) == h("90 50 00 00 00 00 FF")  # inquiries are still answered
    started = time.monotonic()
    wire.write(h("81 01 04 00 02 FF"))
    assert read_packet(wire) == h("90 41 FF")
    wire.write(h("81 01 04 47 01 00 00 00 FF"))  # while starting: not executable (socket 2)
    assert read_packet(wire) == h("90 62 41 FF")
    assert read_packet(wire) == h("90 51 FF")  # power-on done
    assert time.monotonic() - started >= 0.45  # power_on_s = 0.5
    wire.write(h("81 01 04 47 01 00 00 00 FF"))
    assert read_packet(wire) == h("90 41 FF") and read_packet(wire) == h("90 51 FF")


def test_version_inquiry_reports_sony_and_two_sockets(wire: serial.Serial) -> None:
    wire.write(h("81 09 00 02 FF"))
    reply = read_packet(wire)
    assert reply[:4] == h("90 50 00 20") and reply[-2:] == h("02 FF") and len(reply) == 10
    assert vc.decode_version(vp.decode_reply(reply)).sockets == 2


def test_cancel_stops_a_zoom_direct_and_names_its_socket(
    sim: SimFcbCamera, wire: serial.Serial
) -> None:
    wire.write(h("81 01 04 47 04 00 00 00 FF"))
    assert read_packet(wire) == h("90 41 FF")
    wait_for(lambda: sim.position_raw() > 0, 5.0, "the zoom under way")
    wire.write(h("81 21 FF"))
    assert read_packet(wire) == h("90 61 04 FF")  # command cancelled, socket 1
    stopped = sim.position_raw()
    assert 0 < stopped < 0x4000 and not sim.moving()
    wire.write(h("81 22 FF"))
    assert read_packet(wire) == h("90 62 05 FF")  # nothing in socket 2: no socket
    wire.timeout = 0.3
    assert read_packet(wire) == b""  # no completion for the cancelled zoom


def test_a_third_packet_while_two_wait_is_buffer_full(wire: serial.Serial) -> None:
    # Four packets in one write: the first runs at once, two wait (one runs per field), the
    # fourth finds the buffer full.
    wire.write(h("81 09 04 00 FF") * 4)
    replies = [read_packet(wire) for _ in range(4)]
    assert replies.count(h("90 60 03 FF")) == 1
    assert replies.count(h("90 50 02 FF")) == 3


def test_both_sockets_busy_is_buffer_full(wire: serial.Serial) -> None:
    wire.write(h("81 01 04 00 03 FF"))  # standby, then power on: socket 1 held while starting
    assert read_packet(wire) == h("90 41 FF") and read_packet(wire) == h("90 51 FF")
    wire.write(h("81 01 04 00 02 FF"))
    assert read_packet(wire) == h("90 41 FF")
    wire.write(h("81 01 04 00 02 FF"))  # power on again: socket 2, completes at once
    assert read_packet(wire) == h("90 42 FF") and read_packet(wire) == h("90 52 FF")
