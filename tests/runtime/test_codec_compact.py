"""Version 3 (compact) samples: what links send for small messages. Every message type has a
compact layout, round-trips through it, and a forged or foreign compact sample is refused with a
reason instead of building a message."""

from __future__ import annotations

import msgspec
import numpy as np
import pytest

from tests.runtime.test_codec import SAMPLES, _same
from umbra.connectors.codec import FRAMED_MIN_BYTES, MAGIC, Codec, DecodeError
from umbra.connectors.compact import COMPACT_VERSION, compact_type, layout_tag
from umbra.connectors.messages import Twist, Vector, message_types


def _envelope(data: bytes) -> list:
    return msgspec.msgpack.decode(data)


def _forged(tag: str, values: list) -> bytes:
    return msgspec.msgpack.encode([MAGIC, COMPACT_VERSION, tag, values])


TWIST_TAG = layout_tag(Twist)


def test_every_registered_message_type_has_a_compact_layout() -> None:
    codec = Codec()
    for cls in message_types().values():
        assert compact_type(cls) is not None, cls.__name__
        assert codec.compact_reader(cls) is not None, cls.__name__


@pytest.mark.parametrize("sample", SAMPLES, ids=lambda s: type(s).__name__)
def test_every_message_round_trips_as_version_3(sample: msgspec.Struct) -> None:
    codec = Codec()
    data = codec.encode_compact(sample)
    magic, version, name, values = _envelope(data)
    assert (magic, version) == (MAGIC, 3)
    assert name.startswith(type(sample).__name__ + "/")  # the type and its field layout
    assert isinstance(values, list)  # field values in order, no field names on the wire
    _same(codec.decode(data), sample)  # the general path
    _same(codec.decode(data, type(sample)), sample)  # the typed fast path
    read = codec.compact_reader(type(sample))
    assert read is not None
    _same(read(data), sample)


def test_compact_samples_are_smaller_than_version_1() -> None:
    codec = Codec()
    twist = SAMPLES[2]
    compact, v1 = codec.encode_compact(twist), codec.encode(twist)
    assert len(compact) < len(v1)
    assert b"vector" not in compact and b"vector" in v1  # values by position, not by name


def test_the_link_writer_picks_compact_for_small_and_framed_for_large_arrays() -> None:
    codec = Codec()
    write = codec.compact_writer(Vector)
    small = Vector(values=np.zeros(FRAMED_MIN_BYTES // 8 - 1), seq=1)
    large = Vector(values=np.zeros(FRAMED_MIN_BYTES // 8), seq=2)
    assert _envelope(write(small))[1] == 3
    assert write(large)[:4] == b"UMB\x02"
    for sample, data in ((small, write(small)), (large, write(large))):
        _same(codec.decode(data, Vector), sample)
    twist = SAMPLES[2]  # another type through this writer: still encoded, and as its own type
    _same(codec.decode(write(twist), Twist), twist)


def test_compact_arrays_are_read_only_views() -> None:
    codec = Codec()
    got = codec.decode(codec.encode_compact(Vector(values=np.arange(4.0))), Vector)
    assert not got.values.flags.writeable
    with pytest.raises(ValueError):
        got.values[0] = 1.0


def test_the_compact_reader_passes_on_anything_else() -> None:
    codec = Codec()
    read = codec.compact_reader(Twist)
    assert read is not None
    twist = SAMPLES[2]
    assert read(codec.encode(twist)) is None  # version 1: decode() reads it
    assert read(codec.encode_compact(SAMPLES[0])) is None  # another type
    assert read(b"\x00garbage") is None
    assert read(_forged(TWIST_TAG, ["x"])) is None
    _same(codec.decode(codec.encode(twist), Twist), twist)


def _twist_values(**change: object) -> list:
    """The compact values of a twist (stamp, seq, origin, vector, frame), its vector's parts
    changed."""
    values = _envelope(Codec().encode_compact(SAMPLES[2]))[3]
    vector = dict(zip(("dtype", "shape", "data"), values[3], strict=True))
    vector.update(change)
    values[3] = [vector["dtype"], vector["shape"], vector["data"]]
    return values


@pytest.mark.parametrize(
    ("values", "reason"),
    [
        (_twist_values(shape=[-6]), "Expected `int` >= 0"),
        (_twist_values(data=b"\x00" * 47), "bad array <f8"),
        (_twist_values(shape=[7]), "bad array <f8"),
        (_twist_values(dtype="|O8"), "not accepted"),
        (_twist_values(dtype="no such dtype"), "bad array dtype"),
        (_twist_values()[:4], "bad Twist"),
        ([*_twist_values()[:4], 5], "Expected `str`"),
    ],
    ids=[
        "negative shape",
        "short data",
        "shape and data differ",
        "object",
        "dtype",
        "fields",
        "field type",
    ],
)
def test_forged_compact_samples_are_refused_with_a_reason(values: list, reason: str) -> None:
    codec = Codec()
    data = _forged(TWIST_TAG, values)
    for expected in (Twist, None):
        with pytest.raises(DecodeError, match=reason):
            codec.decode(data, expected)


def test_a_producer_with_another_field_layout_is_refused_not_misread() -> None:
    codec = Codec()
    values = _twist_values()
    for tag in ("Twist/00000000", "Twist"):  # another build's layout; no layout at all
        for expected in (Twist, None):
            with pytest.raises(DecodeError, match="another version of the message types"):
                codec.decode(_forged(tag, values), expected)
    _same(codec.decode(_forged(TWIST_TAG, values), Twist), SAMPLES[2])


def test_the_layout_tag_follows_field_names_types_and_order() -> None:
    class A(msgspec.Struct):
        x: float
        y: float

    class B(msgspec.Struct):
        y: float
        x: float

    class C(msgspec.Struct):
        x: float
        y: int

    tags = {layout_tag(A).split("/")[1], layout_tag(B).split("/")[1], layout_tag(C).split("/")[1]}
    assert len(tags) == 3
    assert compact_type(Twist).tag == layout_tag(Twist)


def test_unknown_and_unexpected_compact_types_are_refused() -> None:
    codec = Codec()
    with pytest.raises(DecodeError, match="unknown message type `Nope`"):
        codec.decode(_forged("Nope", []))
    with pytest.raises(DecodeError, match="expected Vector, found Twist"):
        codec.decode(codec.encode_compact(SAMPLES[2]), Vector)
