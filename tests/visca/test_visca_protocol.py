"""VISCA framing against byte strings written out by hand from Sony's FCB command lists."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tests.visca.raw_wire import h
from umbra.modules.calib.visca import commands as vc
from umbra.modules.calib.visca import protocol as vp

# -- encoding ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("packet", "expected"),
    [
        (vp.encode_address_set(), "88 30 01 FF"),
        (vp.encode_if_clear_broadcast(), "88 01 00 01 FF"),
        (vp.encode_if_clear(1), "81 01 00 01 FF"),
        (vp.encode_if_clear(7), "87 01 00 01 FF"),
        (vp.encode_zoom_direct(1, 0x0000), "81 01 04 47 00 00 00 00 FF"),
        (vp.encode_zoom_direct(1, 0x4000), "81 01 04 47 04 00 00 00 FF"),
        (vp.encode_zoom_direct(2, 0x1A2B), "82 01 04 47 01 0A 02 0B FF"),
        (vp.encode_zoom_position_inquiry(1), "81 09 04 47 FF"),
        (vp.encode_zoom_position_inquiry(3), "83 09 04 47 FF"),
        (vp.encode_ack(1, 1), "90 41 FF"),
        (vp.encode_completion(1, 2), "90 52 FF"),
        (vp.encode_completion(2, 0), "A0 50 FF"),
        (vp.encode_error(1, 0, vp.ErrorCode.SYNTAX), "90 60 02 FF"),
        (vp.encode_error(1, 1, vp.ErrorCode.NOT_EXECUTABLE), "90 61 41 FF"),
        (vp.encode_zoom_position_reply(1, 0x2000), "90 50 02 00 00 00 FF"),
        (vp.encode_address_set_reply(2), "88 30 02 FF"),
    ],
)
def test_encode_matches_spec_bytes(packet: bytes, expected: str) -> None:
    assert packet == h(expected)
    assert vp.hex_bytes(packet) == expected


@pytest.mark.parametrize("address", [0, 8, -1])
def test_encode_rejects_bad_address(address: int) -> None:
    with pytest.raises(ValueError, match=r"1\.\.7"):
        vp.encode_zoom_direct(address, 0)


def test_encode_rejects_values_beyond_four_nibbles() -> None:
    with pytest.raises(ValueError, match="0xFFFF"):
        vp.encode_zoom_direct(1, 0x10000)


# -- decoding replies -------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("packet", "expected"),
    [
        ("88 30 02 FF", vp.AddressSetReply(2)),
        ("88 30 04 FF", vp.AddressSetReply(4)),
        ("88 01 00 01 FF", vp.IfClearBroadcastReply()),
        ("90 41 FF", vp.Ack(1, 1)),
        ("90 42 FF", vp.Ack(1, 2)),
        ("A0 41 FF", vp.Ack(2, 1)),
        ("90 51 FF", vp.Completion(1, 1)),
        ("90 50 FF", vp.Completion(1, 0)),
        ("90 50 01 02 03 04 FF", vp.Completion(1, 0, h("01 02 03 04"))),
        ("90 60 01 FF", vp.ErrorReply(1, 0, vp.ErrorCode.MESSAGE_LENGTH)),
        ("90 60 02 FF", vp.ErrorReply(1, 0, vp.ErrorCode.SYNTAX)),
        ("90 60 03 FF", vp.ErrorReply(1, 0, vp.ErrorCode.BUFFER_FULL)),
        ("90 61 04 FF", vp.ErrorReply(1, 1, vp.ErrorCode.CANCELLED)),
        ("90 62 05 FF", vp.ErrorReply(1, 2, vp.ErrorCode.NO_SOCKET)),
        ("90 61 41 FF", vp.ErrorReply(1, 1, vp.ErrorCode.NOT_EXECUTABLE)),
        ("F0 62 41 FF", vp.ErrorReply(7, 2, vp.ErrorCode.NOT_EXECUTABLE)),
        ("90 38 FF", vp.NetworkChange(1)),
    ],
)
def test_decode_reply_from_spec_bytes(packet: str, expected: vp.Reply) -> None:
    assert vp.decode_reply(h(packet)) == expected


@pytest.mark.parametrize(
    ("code", "words"),
    [
        (vp.ErrorCode.SYNTAX, "syntax error"),
        (vp.ErrorCode.BUFFER_FULL, "command buffer full"),
        (vp.ErrorCode.CANCELLED, "command cancelled"),
        (vp.ErrorCode.NO_SOCKET, "no socket"),
        (vp.ErrorCode.NOT_EXECUTABLE, "command not executable"),
    ],
)
def test_error_codes_have_the_manual_wording(code: vp.ErrorCode, words: str) -> None:
    assert vp.decode_reply(vp.encode_error(1, 0, code)).description == words


@pytest.mark.parametrize(
    ("packet", "message"),
    [
        ("90 FF", "need >= 3 bytes"),
        ("90 41", "need >= 3 bytes"),
        ("10 41 FF", "bad reply header 10"),
        ("98 41 FF", "bad reply header 98"),
        ("80 41 FF", "bad reply header 80"),
        ("90 70 FF", "unknown reply"),
        ("90 41 00 FF", "unknown reply"),
        ("90 60 99 FF", "unknown error code 99"),
        ("88 30 09 FF", "unknown broadcast reply"),
        ("90 50 FF 01 FF", "terminator FF inside"),
        ("90 50 " + "00 " * 14 + "FF", "longer than 16"),
    ],
)
def test_decode_reply_rejects_bad_packets_with_the_bytes(packet: str, message: str) -> None:
    with pytest.raises(vp.ViscaDecodeError, match=message):
        vp.decode_reply(h(packet))


@pytest.mark.parametrize(
    ("packet", "raw"),
    [
        ("90 50 00 00 00 00 FF", 0x0000),
        ("90 50 02 00 00 00 FF", 0x2000),
        ("90 50 04 00 00 00 FF", 0x4000),
        ("90 50 01 0A 02 0B FF", 0x1A2B),
        ("90 50 07 0A 0C 00 FF", 0x7AC0),
    ],
)
def test_zoom_position_reply(packet: str, raw: int) -> None:
    assert vp.decode_zoom_position(vp.decode_reply(h(packet))) == raw


@pytest.mark.parametrize(
    "packet",
    ["90 50 01 02 03 FF", "90 51 00 00 00 00 FF", "90 50 10 00 00 00 FF", "90 41 FF"],
)
def test_zoom_position_rejects_other_replies(packet: str) -> None:
    with pytest.raises(vp.ViscaDecodeError):
        vp.decode_zoom_position(vp.decode_reply(h(packet)))


# -- decoding commands (simulator side) -------------------------------------------------------


TELE, WIDE = vc.ZoomDirection.TELE, vc.ZoomDirection.WIDE


@pytest.mark.parametrize(
    ("packet", "expected"),
    [
        ("88 30 01 FF", vc.AddressSetCommand(1)),
        ("88 01 00 01 FF", vc.IfClearCommand(None)),
        ("81 01 00 01 FF", vc.IfClearCommand(1)),
        ("81 01 04 47 02 00 00 00 FF", vc.ZoomDirectCommand(1, 0x2000)),
        ("83 01 04 47 00 0F 0F 0F FF", vc.ZoomDirectCommand(3, 0x0FFF)),
        ("81 09 04 47 FF", vc.ZoomPositionInquiry(1)),
        ("81 01 04 07 00 FF", vc.ZoomStopCommand(1)),
        ("81 01 04 07 02 FF", vc.ZoomMoveCommand(1, TELE, None)),
        ("81 01 04 07 03 FF", vc.ZoomMoveCommand(1, WIDE, None)),
        ("81 01 04 07 20 FF", vc.ZoomMoveCommand(1, TELE, 0)),
        ("82 01 04 07 37 FF", vc.ZoomMoveCommand(2, WIDE, 7)),
        ("81 01 04 00 02 FF", vc.PowerCommand(1, True)),
        ("81 01 04 00 03 FF", vc.PowerCommand(1, False)),
        ("81 09 04 00 FF", vc.PowerInquiry(1)),
        ("81 09 00 02 FF", vc.VersionInquiry(1)),
        ("81 21 FF", vc.CancelCommand(1, 1)),
        ("81 22 FF", vc.CancelCommand(1, 2)),
        ("81 23 FF", vc.UnknownCommand(1, h("81 23 FF"))),
        ("81 01 04 07 28 FF", vc.UnknownCommand(1, h("81 01 04 07 28 FF"))),
        ("81 01 04 07 04 FF", vc.UnknownCommand(1, h("81 01 04 07 04 FF"))),
        ("81 01 04 00 04 FF", vc.UnknownCommand(1, h("81 01 04 00 04 FF"))),
        ("81 01 04 47 20 00 00 00 FF", vc.UnknownCommand(1, h("81 01 04 47 20 00 00 00 FF"))),
    ],
)
def test_decode_command(packet: str, expected: vc.Command) -> None:
    assert vc.decode_command(h(packet)) == expected


@pytest.mark.parametrize(
    ("encoded", "packet"),
    [
        (vc.encode_zoom_stop(1), "81 01 04 07 00 FF"),
        (vc.encode_zoom_move(1, TELE), "81 01 04 07 02 FF"),
        (vc.encode_zoom_move(1, WIDE), "81 01 04 07 03 FF"),
        (vc.encode_zoom_move(1, TELE, 5), "81 01 04 07 25 FF"),
        (vc.encode_zoom_move(3, WIDE, 0), "83 01 04 07 30 FF"),
        (vc.encode_power(1, True), "81 01 04 00 02 FF"),
        (vc.encode_power(1, False), "81 01 04 00 03 FF"),
        (vc.encode_power_inquiry(1), "81 09 04 00 FF"),
        (vc.encode_version_inquiry(1), "81 09 00 02 FF"),
        (vc.encode_cancel(1, 2), "81 22 FF"),
        (vc.encode_power_reply(1, True), "90 50 02 FF"),
        (vc.encode_power_reply(2, False), "A0 50 03 FF"),
        (vc.encode_version_reply(1, 0x0467, 0x0123), "90 50 00 20 04 67 01 23 02 FF"),
    ],
)
def test_encode_fcb_commands_byte_for_byte(encoded: bytes, packet: str) -> None:
    assert encoded == h(packet)
    if packet.startswith("8"):
        assert vc.decode_command(encoded).address == int(packet[1])


def test_version_and_power_replies_decode() -> None:
    version = vc.decode_version(vp.decode_reply(h("90 50 00 20 04 67 01 23 02 FF")))
    assert version == vc.Version(vendor=0x0020, model=0x0467, rom=0x0123, sockets=2)
    assert vc.decode_power(vp.decode_reply(h("90 50 02 FF"))) is True
    assert vc.decode_power(vp.decode_reply(h("90 50 03 FF"))) is False
    with pytest.raises(vp.ViscaDecodeError):
        vc.decode_power(vp.decode_reply(h("90 50 04 FF")))
    with pytest.raises(ValueError, match=r"0\.\.7"):
        vc.encode_zoom_move(1, TELE, 8)


@pytest.mark.parametrize("packet", ["90 41 FF", "80 09 04 47 FF", "01 09 FF", "81 FF"])
def test_decode_command_rejects_non_controller_packets(packet: str) -> None:
    with pytest.raises(vp.ViscaDecodeError):
        vc.decode_command(h(packet))


# -- zoom scaling -----------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("zoom", "raw"),
    [(0.0, 0x0000), (1.0, 0x4000), (0.5, 0x2000), (0.25, 0x1000), (-0.3, 0x0000), (1.7, 0x4000)],
)
def test_normalized_to_raw_is_linear_on_optical_range_and_clamped(zoom: float, raw: int) -> None:
    assert vp.zoom_normalized_to_raw(zoom) == raw


def test_normalized_to_raw_rejects_nan() -> None:
    with pytest.raises(ValueError, match="NaN"):
        vp.zoom_normalized_to_raw(math.nan)


def test_raw_to_normalized_clamps_digital_zoom_to_one() -> None:
    assert vp.zoom_raw_to_normalized(0x6000) == 1.0
    assert vp.zoom_raw_to_normalized(0x1000) == 0.25


def test_every_optical_raw_position_survives_a_round_trip() -> None:
    for raw in range(vp.ZOOM_RAW_WIDE, vp.ZOOM_RAW_OPTICAL_TELE + 1):
        assert vp.zoom_normalized_to_raw(vp.zoom_raw_to_normalized(raw)) == raw


# -- stream splitting -------------------------------------------------------------------------


def test_splitter_handles_packets_cut_anywhere() -> None:
    stream = h("90 41 FF 90 51 FF 90 50 02 00 00 00 FF")
    for cut in range(len(stream) + 1):
        splitter = vp.PacketSplitter()
        packets = splitter.feed(stream[:cut]) + splitter.feed(stream[cut:])
        assert packets == [h("90 41 FF"), h("90 51 FF"), h("90 50 02 00 00 00 FF")]
        assert splitter.errors == 0


def test_splitter_resynchronises_after_garbage_and_counts_it() -> None:
    splitter = vp.PacketSplitter()
    packets = splitter.feed(h("12 34 FF FF 90 41 FF 05 06 90 51 FF 90 50 90 52 FF"))
    # "12 34 FF": no header; lone "FF"; "05 06" before a header; "90 50" lost its terminator.
    assert packets == [h("90 41 FF"), h("90 51 FF"), h("90 52 FF")]
    assert splitter.errors == 4
    assert splitter.discarded_bytes == 3 + 1 + 2 + 2


def test_splitter_drops_an_overlong_run_and_recovers() -> None:
    splitter = vp.PacketSplitter()
    packets = splitter.feed(bytes(range(1, 41)) + h("90 41 FF"))
    assert packets == [h("90 41 FF")]
    assert splitter.errors >= 1
    assert splitter.pending == 0


_SPEC_REPLIES = [
    h("90 41 FF"),
    h("90 52 FF"),
    h("90 50 FF"),
    h("90 50 03 0F 00 01 FF"),
    h("90 61 41 FF"),
    h("88 30 02 FF"),
]


@given(
    garbage=st.binary(max_size=64).map(lambda b: b.replace(b"\xff", b"")),
    replies=st.lists(st.sampled_from(_SPEC_REPLIES), min_size=1, max_size=6),
)
def test_splitter_recovers_every_reply_after_any_garbage(garbage: bytes, replies: list) -> None:
    splitter = vp.PacketSplitter()
    packets = splitter.feed(garbage + b"".join(replies))
    assert packets[-len(replies) :] == replies
    assert [vp.decode_reply(p) for p in packets[-len(replies) :]]  # all decode
    if garbage:
        assert splitter.errors >= 1
