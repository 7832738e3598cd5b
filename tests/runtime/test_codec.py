"""The link and recording encoding: every type round-trips, bad bytes are refused with a reason."""

from __future__ import annotations

import msgspec
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from umbra.connectors.codec import FRAMED_MIN_BYTES, Codec, DecodeError
from umbra.connectors.messages import Contour, Image, JointRates, Scalar, Text, Twist, Vector
from umbra.connectors.path_messages import VcrAction, VcrCommand, VcrMode, VcrState
from umbra.connectors.ptu_messages import PtuCommand, PtuMode
from umbra.connectors.scene_messages import SceneObjects, SolidKind
from umbra.connectors.sketch_messages import PrimitiveKind, SketchPrimitive

SAMPLES = [
    Scalar(value=2.5, stamp=1.25, seq=3),
    Text(text="seed 320,240", seq=9),
    Twist(vector=np.arange(6.0), frame="camera", stamp=0.5, seq=1),
    Vector(values=np.ones((2, 3), np.float32), seq=2),
    Vector(values=np.zeros(0)),
    JointRates(names=("j1", "j2"), rates=np.array([0.1, -0.2]), seq=4),
    Contour(
        vertices=np.arange(20.0).reshape(10, 2),
        centroid=np.array([1.0, 2.0]),
        area=3.0,
        orientation=0.1,
        axes=np.array([4.0, 2.0]),
        offending=np.array([1, 5], np.int64),
    ),
    Image(pixels=np.arange(120 * 160 * 3, dtype=np.uint8).reshape(120, 160, 3), seq=5),
]


def _same(a: msgspec.Struct, b: msgspec.Struct) -> None:
    assert type(a) is type(b)
    for name in a.__struct_fields__:
        x, y = getattr(a, name), getattr(b, name)
        if isinstance(x, np.ndarray):
            assert x.dtype == y.dtype and x.shape == y.shape
            np.testing.assert_array_equal(x, y)
        else:
            assert x == y, name


@pytest.mark.parametrize("sample", SAMPLES, ids=lambda s: type(s).__name__)
@pytest.mark.parametrize("framed", [False, True], ids=["v1", "framed"])
@pytest.mark.parametrize("typed", [False, True], ids=["any", "typed"])
def test_every_message_round_trips(sample: msgspec.Struct, framed: bool, typed: bool) -> None:
    codec = Codec()
    data = codec.encode_framed(sample) if framed else codec.encode(sample)
    if framed and isinstance(sample, Image):
        assert data[:4] == b"UMB\x02"  # large arrays: the framed layout
    _same(codec.decode(data, type(sample) if typed else None), sample)


def test_arrays_of_many_shapes_share_the_caches_without_mixing_them() -> None:
    codec = Codec()
    shapes = [(6,), (3, 2), (2, 3), (1, 6), (6, 1), (0,), (2, 0, 3)]
    for _ in range(2):  # the second round reads the cached heads
        for shape in shapes:
            values = np.arange(int(np.prod(shape)), dtype=np.float64).reshape(shape)
            got = codec.decode(codec.encode(Vector(values=values)), Vector)
            assert got.values.shape == shape
            np.testing.assert_array_equal(got.values, values)


def test_views_and_non_contiguous_arrays_encode_their_values() -> None:
    codec = Codec()
    base = np.arange(64.0).reshape(8, 8)
    for values in (base[::2, 1::3], base.T, base[3]):
        got = codec.decode(codec.encode_framed(Vector(values=values)), Vector)
        np.testing.assert_array_equal(got.values, values)


def test_decoded_arrays_are_read_only_views() -> None:
    codec = Codec()
    big = Vector(values=np.ones(FRAMED_MIN_BYTES // 8 + 1))
    for data in (codec.encode(SAMPLES[2]), codec.encode_framed(big)):
        msg = codec.decode(data)
        array = msg.vector if isinstance(msg, Twist) else msg.values
        assert not array.flags.writeable


def test_bad_bytes_are_refused_with_a_reason() -> None:
    codec = Codec()
    good = codec.encode(SAMPLES[2])
    framed = codec.encode_framed(SAMPLES[-1])
    cases = {
        b"": "not an umbra sample",
        b"hello world": "not an umbra sample",
        msgspec.msgpack.encode(["other", 1, "Twist", {}]): "magic",
        msgspec.msgpack.encode(["umbra", 7, "Twist", {}]): "encoding version 7",
        msgspec.msgpack.encode(["umbra", 1, "Nope", {}]): "unknown message type `Nope`",
        good[:-3]: "truncated",
        framed[:100]: "truncated",
        b"UMB\x02" + b"\xff\xff\xff\x00": "truncated",
    }
    for data, reason in cases.items():
        with pytest.raises(DecodeError, match=reason):
            codec.decode(data)
    with pytest.raises(DecodeError, match="expected Scalar, found Twist"):
        codec.decode(good, Scalar)


def test_object_arrays_are_never_encoded_or_decoded() -> None:
    codec = Codec()
    with pytest.raises(NotImplementedError):
        codec.encode(Vector(values=np.array([object()], dtype=object)))
    forged = bytearray(codec.encode(Vector(values=np.zeros(2))))
    at = forged.find(b"<f8")
    forged[at : at + 3] = b"|O8"
    with pytest.raises(DecodeError):
        codec.decode(bytes(forged), Vector)


@settings(max_examples=60, deadline=None)
@given(
    hnp.arrays(
        dtype=st.sampled_from([np.uint8, np.int32, np.float32, np.float64, np.complex128]),
        shape=hnp.array_shapes(min_dims=1, max_dims=3, min_side=0, max_side=9),
    ),
    st.booleans(),
)
def test_any_numeric_array_round_trips(values: np.ndarray, framed: bool) -> None:
    codec = Codec()
    sample = Vector(values=values, seq=1)
    data = codec.encode_framed(sample) if framed else codec.encode(sample)
    got = codec.decode(data, Vector).values
    assert got.dtype == values.dtype and got.shape == values.shape
    np.testing.assert_array_equal(got, values)


@pytest.mark.parametrize(
    ("message", "field"),
    [
        (PtuCommand(mode=PtuMode.POINT), "mode"),
        (VcrCommand(action=VcrAction.PLAY), "action"),
        (VcrState(path_id="p", mode=VcrMode.PLAYING), "mode"),
        (SketchPrimitive(primitive_id="p", kind=PrimitiveKind.LINE), "kind"),
    ],
)
def test_a_code_the_type_does_not_declare_is_refused_on_decoding(
    message: msgspec.Struct, field: str
) -> None:
    """A code field (an enum) decodes only to a declared member: a peer's unknown word is
    refused at the link, before any module reads it."""
    codec = Codec()
    decoded = codec.decode(codec.encode(message), type(message))
    assert getattr(decoded, field) is getattr(message, field)  # the member itself
    made_up = msgspec.structs.replace(message, **{field: "sideways"})  # as a foreign peer might
    for framed in (False, True):
        data = codec.encode_framed(made_up) if framed else codec.encode(made_up)
        with pytest.raises(DecodeError):
            codec.decode(data, type(message))


def test_a_solid_kind_the_type_does_not_declare_is_refused_on_decoding() -> None:
    """The renderers draw a box or a cylinder; a third word from a peer never reaches them."""
    codec = Codec()
    objects = SceneObjects(
        names=("a", "b"),
        kinds=(SolidKind.BOX, SolidKind.CYLINDER),
        poses=np.stack([np.eye(4)] * 2),
        sizes=np.ones((2, 3)),
        colors=np.zeros((2, 3), np.uint8),
    )
    assert codec.decode(codec.encode(objects), SceneObjects).kinds == objects.kinds
    unknown = codec.encode(objects).replace(b"cylinder", b"triangle")  # a peer's unknown word
    with pytest.raises(DecodeError):
        codec.decode(unknown, SceneObjects)
    with pytest.raises(ValueError, match="sphere"):  # nor is one made in this process
        msgspec.structs.replace(objects, kinds=("box", "sphere"))
