"""The simulated FCB camera on a real pty, driven with raw bytes through pyserial."""

from __future__ import annotations

import subprocess
import sys

import pytest
import serial

from tests.poll import wait_for
from tests.visca.raw_wire import h, read_packet
from umbra.modules.calib.visca import protocol as vp
from umbra.modules.calib.visca.sim_camera import Fault, SimFcbCamera


def test_address_set_and_if_clear_answer_as_the_manual_says(wire: serial.Serial) -> None:
    wire.write(h("88 30 01 FF"))
    assert read_packet(wire) == h("88 30 02 FF")
    wire.write(h("88 01 00 01 FF"))
    assert read_packet(wire) == h("88 01 00 01 FF")
    wire.write(h("81 01 00 01 FF"))
    assert read_packet(wire) == h("90 50 FF")


def test_address_set_renumbers_the_camera() -> None:
    with SimFcbCamera(address=3) as camera, serial.Serial(camera.path, timeout=0.3) as port:
        port.write(h("81 09 04 47 FF"))  # no camera 1 yet: nobody answers
        assert port.read_until(b"\xff") == b""
        port.write(h("83 09 04 47 FF"))
        assert port.read_until(b"\xff") == h("B0 50 00 00 00 00 FF")
        port.write(h("88 30 01 FF"))
        assert port.read_until(b"\xff") == h("88 30 02 FF")
        assert camera.address == 1
        port.write(h("81 09 04 47 FF"))
        assert port.read_until(b"\xff") == h("90 50 00 00 00 00 FF")


def test_zoom_direct_acks_then_completes_on_arrival(sim: SimFcbCamera, wire: serial.Serial) -> None:
    wire.write(h("81 01 04 47 02 00 00 00 FF"))
    assert read_packet(wire) == h("90 41 FF")
    wire.write(h("81 09 04 47 FF"))
    moving = vp.decode_zoom_position(vp.decode_reply(read_packet(wire)))
    assert 0 <= moving < 0x2000  # half the range takes half of full_range_s = 1.0 s
    assert read_packet(wire) == h("90 51 FF")
    assert sim.position_raw() == 0x2000
    wire.write(h("81 09 04 47 FF"))
    assert read_packet(wire) == h("90 50 02 00 00 00 FF")


def test_new_zoom_during_a_move_takes_the_other_socket_and_cancels_the_first(
    sim: SimFcbCamera, wire: serial.Serial
) -> None:
    wire.write(h("81 01 04 47 04 00 00 00 FF"))
    assert read_packet(wire) == h("90 41 FF")
    wire.write(h("81 01 04 47 01 00 00 00 FF"))
    assert read_packet(wire) == h("90 42 FF")
    assert read_packet(wire) == h("90 61 04 FF")
    assert read_packet(wire) == h("90 52 FF")
    assert sim.position_raw() == 0x1000


def test_if_clear_stops_a_running_zoom_without_completion(
    sim: SimFcbCamera, wire: serial.Serial
) -> None:
    wire.write(h("81 01 04 47 04 00 00 00 FF"))
    assert read_packet(wire) == h("90 41 FF")
    wait_for(lambda: sim.position_raw() > 0, 5.0, "the zoom under way")
    wire.write(h("81 01 00 01 FF"))
    assert read_packet(wire) == h("90 50 FF")
    stopped = sim.position_raw()
    assert 0 < stopped < 0x4000
    wire.timeout = 0.3
    assert read_packet(wire) == b""  # no completion for the cleared command
    assert sim.position_raw() == stopped


def test_beyond_optical_tele_stops_at_tele(sim: SimFcbCamera, wire: serial.Serial) -> None:
    wire.write(h("81 01 04 47 07 0A 0C 00 FF"))
    assert read_packet(wire) == h("90 41 FF")
    assert read_packet(wire) == h("90 51 FF")
    assert sim.position_raw() == 0x4000


def test_unknown_command_gets_syntax_error(wire: serial.Serial) -> None:
    wire.write(h("81 01 04 33 02 FF"))  # backlight on: not simulated
    assert read_packet(wire) == h("90 60 02 FF")
    wire.write(h("81 01 04 3F 01 06 FF"))  # memory set of memory 6: an FCB has 0..5
    assert read_packet(wire) == h("90 60 02 FF")
    wire.write(h("81 01 04 07 28 FF"))  # variable zoom speed 8: out of range
    assert read_packet(wire) == h("90 60 02 FF")


@pytest.mark.parametrize(
    ("request_bytes", "code", "reply"),
    [
        ("81 09 04 47 FF", vp.ErrorCode.SYNTAX, "90 60 02 FF"),
        ("81 09 04 47 FF", vp.ErrorCode.BUFFER_FULL, "90 60 03 FF"),
        ("81 01 04 47 02 00 00 00 FF", vp.ErrorCode.NOT_EXECUTABLE, "90 61 41 FF"),
    ],
)
def test_error_fault_answers_every_request_with_the_error(
    sim: SimFcbCamera, wire: serial.Serial, request_bytes: str, code: vp.ErrorCode, reply: str
) -> None:
    sim.inject(Fault.ERROR, code)
    wire.write(h(request_bytes))
    assert read_packet(wire) == h(reply)


def test_silent_fault_says_nothing_and_heals(sim: SimFcbCamera, wire: serial.Serial) -> None:
    sim.inject(Fault.SILENT)
    wire.timeout = 0.3
    wire.write(h("81 09 04 47 FF"))
    assert read_packet(wire) == b""
    sim.heal()
    wire.write(h("81 09 04 47 FF"))
    assert read_packet(wire) == h("90 50 00 00 00 00 FF")


def test_garble_fault_sends_bytes_nobody_can_decode(sim: SimFcbCamera, wire: serial.Serial) -> None:
    sim.inject(Fault.GARBLE)
    for _ in range(5):
        wire.write(h("81 09 04 47 FF"))
        garbled = read_packet(wire)
        assert garbled.endswith(b"\xff")
        splitter = vp.PacketSplitter()
        assert splitter.feed(garbled) == []
        assert splitter.errors == 1


def test_standalone_process_prints_a_pty_path_that_answers() -> None:
    process = subprocess.Popen(
        [sys.executable, "-m", "umbra.modules.calib.visca.sim_camera", "--full-range-s", "0.5"],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert process.stdout is not None
        path = process.stdout.readline().strip()
        assert path.startswith("/dev/")
        with serial.Serial(path, 9600, timeout=2.0) as port:
            port.write(h("88 30 01 FF"))
            assert port.read_until(b"\xff") == h("88 30 02 FF")
    finally:
        process.terminate()
        assert process.wait(timeout=5.0) == 0
