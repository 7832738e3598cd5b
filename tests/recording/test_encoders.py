"""Encodings of each message type, read back with the official Foxglove classes and JSON Schema."""

from __future__ import annotations

import json
import re

import cv2
import jsonschema
import numpy as np
import pytest
from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.ImageAnnotations_pb2 import ImageAnnotations
from foxglove_schemas_protobuf.PointsAnnotation_pb2 import PointsAnnotation
from foxglove_schemas_protobuf.RawImage_pb2 import RawImage
from google.protobuf.descriptor_pb2 import FileDescriptorSet
from scipy.spatial.transform import Rotation

from umbra.connectors.messages import (
    CameraModel,
    Contour,
    Image,
    JointRates,
    JointState,
    Pose,
    Poses,
    Scalar,
    Status,
    Text,
    Twist,
    Vector,
    ZoomState,
    message_types,
)
from umbra.runtime.recording.encoders import channel_encodings, decode_primary
from umbra.runtime.recording.json_codec import decode_json, encode_json, json_schema

RNG = np.random.default_rng(7)


def _image() -> Image:
    return Image(pixels=RNG.integers(0, 256, (48, 64, 3), dtype=np.uint8), stamp=1.25, seq=3)


def _pose() -> Pose:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("xyz", [0.3, -0.2, 1.1]).as_matrix()
    T[:3, 3] = [0.63, -0.04, 0.35]
    return Pose(matrix=T, parent="table", child="camera", stamp=0.5, seq=9)


def _contour() -> Contour:
    return Contour(
        vertices=np.array([[10.0, 12.5], [40.25, 12.0], [40.0, 30.0], [11.0, 29.5]]),
        centroid=np.array([25.3, 21.0]),
        area=512.5,
        orientation=0.01,
        axes=np.array([30.0, 17.5]),
        offending=np.array([2], dtype=np.int64),
        stamp=2.0,
        seq=4,
    )


SAMPLES = [
    Scalar(value=-3.5, stamp=0.1, seq=1),
    Vector(values=np.array([1.0, np.nan, np.inf]), stamp=0.2, seq=2),
    Text(text="seed 320,240", stamp=0.3, seq=3),
    Twist(vector=np.array([0.01, -0.02, 0.03, 0.0, 0.1, -0.2]), frame="camera", stamp=0.4, seq=4),
    JointState(names=("j1", "j2"), position=np.array([0.1, -0.2]), velocity=np.array([0.0, 1e-9])),
    JointRates(names=("j1", "j2"), rates=np.array([0.5, -0.5]), near_limit=True),
    ZoomState(zoom=0.25, raw=4096, moving=True),
    Status(stage="approach", values={"error_x": 0.0117, "error_z": 0.18}, assist=False),
    CameraModel(fx=800.0, fy=801.0, u0=640.0, v0=360.0, dist=np.array([0.1, -0.2, 0, 0, 0.01])),
    _contour(),
]


def _equal(a: object, b: object) -> bool:
    if type(a) is not type(b):
        return False
    for name in a.__struct_fields__:  # type: ignore[attr-defined]
        va, vb = getattr(a, name), getattr(b, name)
        if isinstance(va, np.ndarray):
            if va.dtype != vb.dtype or va.shape != vb.shape:
                return False
            if not np.array_equal(va, vb, equal_nan=va.dtype.kind == "f"):
                return False
        elif isinstance(va, float) and va != va:  # NaN is NaN
            if not (isinstance(vb, float) and vb != vb):
                return False
        elif va != vb:
            return False
    return True


@pytest.mark.parametrize("sample", SAMPLES, ids=lambda s: type(s).__name__)
def test_json_round_trip_is_exact_and_validates_against_its_schema(sample: object) -> None:
    data = encode_json(sample)  # type: ignore[arg-type]
    schema = json_schema(type(sample))  # type: ignore[arg-type]
    obj = json.loads(data)
    jsonschema.Draft202012Validator.check_schema(schema)
    jsonschema.validate(obj, schema)  # non-finite values too: the schema says where they go
    if isinstance(sample, Vector):  # NaN and infinities: the field moves to `_nonfinite`
        assert "values" not in obj
        assert obj["_nonfinite"] == {"values": ["1.0", "NaN", "Infinity"]}
        obj["values"] = obj.pop("_nonfinite")
    assert set(obj) | {"_nonfinite"} == set(schema["properties"])  # every field typed
    assert schema["title"] == f"umbra.{type(sample).__name__}"
    back = decode_json(type(sample), data)  # type: ignore[arg-type]
    assert _equal(sample, back)  # exact: NaN, +inf and -inf read back as they were


NONFINITE = [
    ZoomState(zoom=float("nan"), raw=0, stamp=0.5, seq=1),
    Scalar(value=float("-inf"), stamp=0.5, seq=2),
    Status(stage="track", values={"error_x": float("inf"), "error_z": 0.25}, stamp=0.5, seq=3),
    Vector(values=np.array([[np.nan, 1e-300], [-np.inf, 0.1]]), stamp=0.5, seq=4),
]


@pytest.mark.parametrize("sample", NONFINITE, ids=lambda s: type(s).__name__)
def test_non_finite_values_validate_against_their_schema_and_read_back_exactly(
    sample: object,
) -> None:
    data = encode_json(sample)  # type: ignore[arg-type]
    schema = json_schema(type(sample))  # type: ignore[arg-type]
    obj = json.loads(data)  # strict JSON: no NaN or Infinity tokens
    assert b"NaN," not in data and b"Infinity," not in data and b"null" not in data
    jsonschema.validate(obj, schema)
    assert obj["_nonfinite"], obj
    assert _equal(sample, decode_json(type(sample), data))  # type: ignore[arg-type]
    # the schema refuses what the old recordings wrote: null where a number belongs
    old = dict(obj, **{"zoom": None} if "zoom" in obj["_nonfinite"] else {"value": None})
    if isinstance(sample, (ZoomState, Scalar)):
        with pytest.raises(jsonschema.ValidationError):
            jsonschema.validate(old, schema)
    # a map's own value that is not finite leaves the others plottable
    if isinstance(sample, Status):
        assert obj["values"] == {"error_z": 0.25}
        assert obj["_nonfinite"] == {"values.error_x": ["Infinity"]}


def test_a_malformed_nonfinite_entry_is_refused() -> None:
    good = json.loads(encode_json(NONFINITE[0]))
    for bad, why in (
        ({"zoom": "NaN"}, "list of strings"),
        ({"zoom": ["many"]}, "not numbers"),
        ([1], "must be an object"),
    ):
        with pytest.raises(ValueError, match=why):
            decode_json(ZoomState, json.dumps({**good, "_nonfinite": bad}).encode())
    both = json.dumps({**good, "zoom": 0.5}).encode()
    with pytest.raises(ValueError, match="both"):
        decode_json(ZoomState, both)


def test_every_message_type_has_a_schema_that_is_not_empty() -> None:
    for msg_type in message_types().values():
        for enc in channel_encodings(msg_type, "jpeg"):
            assert enc.schema_name and len(enc.schema_data) > 100, msg_type
            if enc.schema_encoding == "protobuf":
                names = {f.name for f in FileDescriptorSet.FromString(enc.schema_data).file}
                assert any(n.startswith("foxglove/") for n in names)


def test_raw_image_decodes_with_the_official_class_to_the_same_pixels() -> None:
    img = _image()
    (enc,) = channel_encodings(Image, "raw")
    raw = RawImage.FromString(enc.encode(img))
    assert (raw.width, raw.height, raw.encoding, raw.step) == (64, 48, "bgr8", 64 * 3)
    assert raw.frame_id == "camera"
    assert raw.timestamp.seconds == 1 and raw.timestamp.nanos == 250_000_000
    pixels = np.frombuffer(raw.data, np.uint8).reshape(48, 64, 3)
    assert np.array_equal(pixels, img.pixels)
    back = decode_primary(Image, enc.schema_name, enc.encode(img), 3)
    assert np.array_equal(back.pixels, img.pixels) and back.stamp == img.stamp


@pytest.mark.parametrize("fmt", ["jpeg", "png"])
def test_compressed_images_decode_with_opencv(fmt: str) -> None:
    smooth = np.zeros((48, 64, 3), np.uint8)
    smooth[10:30, 20:50] = (40, 200, 60)  # a green patch on black, BGR
    img = Image(pixels=smooth, stamp=0.5)
    (enc,) = channel_encodings(Image, fmt, jpeg_quality=95)
    comp = CompressedImage.FromString(enc.encode(img))
    assert comp.format == fmt and comp.frame_id == "camera"
    pixels = cv2.imdecode(np.frombuffer(comp.data, np.uint8), cv2.IMREAD_COLOR)
    err = np.abs(pixels.astype(int) - smooth.astype(int))
    assert err.max() == 0 if fmt == "png" else err.mean() < 3.0


def test_pose_is_a_frame_transform_with_the_same_rotation_and_translation() -> None:
    pose = _pose()
    (enc,) = channel_encodings(Pose)
    ft = FrameTransform.FromString(enc.encode(pose))
    assert (ft.parent_frame_id, ft.child_frame_id) == ("table", "camera")
    t = [ft.translation.x, ft.translation.y, ft.translation.z]
    assert np.allclose(t, [0.63, -0.04, 0.35], atol=1e-15)
    q = [ft.rotation.x, ft.rotation.y, ft.rotation.z, ft.rotation.w]
    assert np.allclose(Rotation.from_quat(q).as_matrix(), pose.matrix[:3, :3], atol=1e-14)
    back = decode_primary(Pose, enc.schema_name, enc.encode(pose), 9)
    assert np.allclose(back.matrix, pose.matrix, atol=1e-14) and back.seq == 9


def _link_poses() -> Poses:
    from umbra.modules.arm.dh import puma560

    T = puma560().frames([0.1, -0.4, 0.3, 0.2, -0.5, 0.7])[1:]
    names = ("link1", "link2", "link3", "link4", "link5", "flange")
    return Poses(matrices=T, children=names, frame="base", stamp=2.5, seq=4)


def _T(t: FrameTransform) -> np.ndarray:
    T = np.eye(4)
    q = [t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w]
    T[:3, :3] = Rotation.from_quat(q).as_matrix()
    T[:3, 3] = [t.translation.x, t.translation.y, t.translation.z]
    return T


def test_poses_are_one_frame_transforms_message_chaining_each_link_to_the_one_before() -> None:
    poses = _link_poses()
    (enc,) = channel_encodings(Poses, offset=1.7e9)
    assert enc.schema_name == "foxglove.FrameTransforms"
    fts = FrameTransforms.FromString(enc.encode(poses))
    assert [t.child_frame_id for t in fts.transforms] == list(poses.children)
    parents = [t.parent_frame_id for t in fts.transforms]
    assert parents == ["base", "link1", "link2", "link3", "link4", "link5"]  # a chain
    T_base = np.eye(4)
    for t, T in zip(fts.transforms, poses.matrices, strict=True):
        assert t.timestamp.ToNanoseconds() == 1_700_000_002_500_000_000  # stamp + wall offset
        T_base = T_base @ _T(t)  # what a viewer's transform tree composes
        assert np.allclose(T_base, T, atol=1e-12)
    # the link from link2 to link3 is the arm's own: its length does not depend on the base
    step = fts.transforms[2]
    expected = np.linalg.inv(poses.matrices[1]) @ poses.matrices[2]
    assert np.allclose(_T(step), expected, atol=1e-12)
    back = decode_primary(Poses, enc.schema_name, enc.encode(poses), 4)
    assert back.children == poses.children and back.frame == "base"
    assert back.stamp == pytest.approx(1.7e9 + 2.5, abs=1e-6)
    assert np.allclose(back.matrices, poses.matrices, atol=1e-12)


def test_a_star_of_frame_transforms_from_older_recordings_still_reads_back() -> None:
    poses = _link_poses()
    star = FrameTransforms(
        transforms=[
            FrameTransform(parent_frame_id="base", child_frame_id=c) for c in poses.children
        ]
    )
    for ft, T in zip(star.transforms, poses.matrices, strict=True):
        x, y, z, w = Rotation.from_matrix(T[:3, :3]).as_quat()
        ft.rotation.x, ft.rotation.y, ft.rotation.z, ft.rotation.w = x, y, z, w
        ft.translation.x, ft.translation.y, ft.translation.z = T[:3, 3]
    back = decode_primary(Poses, "foxglove.FrameTransforms", star.SerializeToString(), 1)
    assert np.allclose(back.matrices, poses.matrices, atol=1e-12)


def test_joint_state_is_foxglove_joint_states_with_the_gripper_as_a_last_joint() -> None:
    from foxglove_schemas_protobuf.JointStates_pb2 import JointStates

    state = JointState(
        names=("j1", "j2", "j3"),
        position=np.array([0.1, -0.2, 1.5]),
        velocity=np.array([0.0, 0.25, -1.0]),
        gripper=0.75,
        stamp=3.0,
        seq=8,
    )
    (enc,) = channel_encodings(JointState, offset=10.0)
    assert enc.schema_name == "foxglove.JointStates"
    js = JointStates.FromString(enc.encode(state))
    assert js.timestamp.ToNanoseconds() == 13_000_000_000
    assert [j.name for j in js.joints] == ["j1", "j2", "j3", "gripper"]
    assert [j.position for j in js.joints] == [0.1, -0.2, 1.5, 0.75]
    assert [j.velocity for j in js.joints[:3]] == [0.0, 0.25, -1.0]
    assert not js.joints[3].HasField("velocity") and not js.joints[0].HasField("effort")
    back = decode_primary(JointState, enc.schema_name, enc.encode(state), 8)
    assert back.names == state.names and back.gripper == 0.75 and back.seq == 8
    assert np.array_equal(back.position, state.position)
    assert np.array_equal(back.velocity, state.velocity)
    no_rates = JointState(names=("j1",), position=np.array([0.5]))
    back = decode_primary(JointState, enc.schema_name, enc.encode(no_rates), 0)
    assert back.velocity.size == 0 and back.position.tolist() == [0.5]
    with pytest.raises(ValueError, match="kept for the gripper"):
        enc.encode(JointState(names=("gripper",), position=np.array([0.0])))


def test_a_camera_model_names_its_frame_and_the_transform_from_its_mount() -> None:
    T = np.eye(4)
    T[:3, 3] = [0.0026, -0.0412, -0.0056]
    model = CameraModel(
        fx=800.0,
        fy=800.0,
        u0=320.0,
        v0=240.0,
        mount="cam_left",
        frame="left_camera",
        T_mount_camera=T,
        stamp=1.0,
    )
    encs = channel_encodings(CameraModel)
    assert [e.suffix for e in encs] == ["", "/calibration", "/mount"]
    calib = CameraCalibration.FromString(encs[1].encode(model))
    mount = FrameTransform.FromString(encs[2].encode(model))
    assert calib.frame_id == "left_camera" == mount.child_frame_id
    assert mount.parent_frame_id == "cam_left"
    assert np.allclose(_T(mount), T, atol=1e-15)
    same = CameraModel(fx=800.0, fy=800.0, u0=320.0, v0=240.0, mount="camera", frame="camera")
    assert encs[2].encode(same) == b""  # nothing to write: a frame is not its own parent


def test_frame_transforms_that_are_not_one_poses_sample_are_refused() -> None:
    (enc,) = channel_encodings(Poses)
    fts = FrameTransforms.FromString(enc.encode(_link_poses()))
    fts.transforms[2].parent_frame_id = "table"
    with pytest.raises(ValueError, match="form a chain or share a parent"):
        decode_primary(Poses, enc.schema_name, fts.SerializeToString(), 0)
    fts.transforms[2].parent_frame_id = "link2"
    fts.transforms[3].translation.z = float("nan")
    with pytest.raises(ValueError, match="not finite"):
        decode_primary(Poses, enc.schema_name, fts.SerializeToString(), 0)
    with pytest.raises(ValueError, match="1 to 1024 transforms, found 0"):
        decode_primary(Poses, enc.schema_name, FrameTransforms().SerializeToString(), 0)
    many = FrameTransforms(transforms=[fts.transforms[0]] * 1025)
    with pytest.raises(ValueError, match="found 1025"):
        decode_primary(Poses, enc.schema_name, many.SerializeToString(), 0)
    short = Poses(matrices=np.eye(4)[None], children=("a", "b"), frame="base")
    with pytest.raises(ValueError, match="1 matrices for 2 children"):
        enc.encode(short)


def test_a_channel_whose_schema_carries_another_type_is_refused() -> None:
    """The channel's declared type and its schema must agree: a recording that says Contour on
    a FrameTransforms schema (or a JSON schema of another type) is not read as either."""
    (poses,) = channel_encodings(Poses)
    with pytest.raises(
        ValueError, match=re.escape("foxglove.FrameTransforms carries Poses, not Contour")
    ):
        decode_primary(Contour, poses.schema_name, poses.encode(_link_poses()), 0)
    with pytest.raises(ValueError, match=re.escape("foxglove.RawImage carries Image, not Pose")):
        decode_primary(Pose, "foxglove.RawImage", b"", 0)
    twist = Twist(vector=np.zeros(6), frame="tool")
    (json_twist,) = channel_encodings(Twist)
    with pytest.raises(ValueError, match=re.escape("umbra.Twist carries Twist, not Scalar")):
        decode_primary(Scalar, json_twist.schema_name, json_twist.encode(twist), 0)


def test_contour_view_draws_the_outline_as_a_closed_line_on_the_image() -> None:
    c = _contour()
    primary, view = channel_encodings(Contour)
    assert view.suffix == "/annotations" and view.schema_name == "foxglove.ImageAnnotations"
    ann = ImageAnnotations.FromString(view.encode(c))
    outline = ann.points[0]
    assert outline.type == PointsAnnotation.LINE_LOOP
    assert [(p.x, p.y) for p in outline.points] == [tuple(v) for v in c.vertices.tolist()]
    assert outline.timestamp.seconds == 2 and outline.timestamp.nanos == 0
    assert ann.texts[0].text == "tracking"
    assert _equal(decode_primary(Contour, primary.schema_name, primary.encode(c), 4), c)


def test_camera_model_view_is_a_camera_calibration() -> None:
    cam = SAMPLES[8]
    _primary, view, _mount = channel_encodings(CameraModel)
    cal = CameraCalibration.FromString(view.encode(cam))  # type: ignore[arg-type]
    assert (cal.width, cal.height, cal.distortion_model) == (640, 480, "plumb_bob")
    assert list(cal.K) == [800.0, 0.0, 640.0, 0.0, 801.0, 360.0, 0.0, 0.0, 1.0]
    assert list(cal.P)[:3] == [800.0, 0.0, 640.0] and list(cal.D)[:2] == [0.1, -0.2]


def test_a_compressed_image_declaring_too_many_pixels_is_refused_before_decoding() -> None:
    (enc,) = channel_encodings(Image, "jpeg")
    data = bytearray(CompressedImage.FromString(enc.encode(_image())).data)
    i = 2
    while data[i + 1] != 0xC0:  # walk the JPEG markers to the frame header
        i += 2 + int.from_bytes(data[i + 2 : i + 4], "big")
    data[i + 5 : i + 9] = (60000).to_bytes(2, "big") * 2  # height, width
    forged = CompressedImage(data=bytes(data), format="jpeg").SerializeToString()
    with pytest.raises(ValueError, match="declares 60000 x 60000 pixels"):
        decode_primary(Image, "foxglove.CompressedImage", forged, 1)
    with pytest.raises(ValueError, match="neither a PNG nor a JPEG"):
        junk = CompressedImage(data=b"GIF89a" + bytes(20), format="jpeg").SerializeToString()
        decode_primary(Image, "foxglove.CompressedImage", junk, 1)


def test_json_arrays_must_be_numeric_and_match_their_shape() -> None:
    good = json.loads(encode_json(SAMPLES[3]))
    for arrays, why in (
        ({"vector": {"dtype": "|O", "shape": [6]}}, "is not numeric"),
        ({"vector": {"dtype": "<f8", "shape": [7]}}, "cannot reshape"),
    ):
        bad = json.dumps({**good, "_arrays": arrays}).encode()
        with pytest.raises(ValueError, match=why):
            decode_json(Twist, bad)


def test_every_json_schema_is_one_foxglove_and_lichtblick_read() -> None:
    from tests.recording.viewer_rules import viewer_datatypes

    for name, msg_type in message_types().items():
        schema = json_schema(msg_type)
        types = viewer_datatypes(schema, schema["title"])  # raises where the viewer would
        fields = types[schema["title"]]
        assert set(fields) == set(schema["properties"]), name  # every field has a viewer type
    twist = viewer_datatypes(json_schema(Twist), "umbra.Twist")["umbra.Twist"]
    assert twist["vector"] == "float64[]" and twist["stamp"] == "float64"  # plots vector[2]
    status = viewer_datatypes(json_schema(Status), "umbra.Status")
    assert status["umbra.Status"]["values"] == "umbra.Status.values"  # values.error_x: an object
    state = viewer_datatypes(json_schema(JointState), "umbra.JointState")["umbra.JointState"]
    assert state["names"] == "string[]" and state["position"] == "float64[]"
    # what the rules refuse: a field of two types, an array without items, a map without properties
    for bad in (
        {"type": ["number", "null"]},
        {"type": "array", "description": "nested lists"},
        {"type": "object", "additionalProperties": {"type": "number"}},
    ):
        with pytest.raises(ValueError):
            viewer_datatypes({"type": "object", "properties": {"x": bad}}, "bad")


def test_arrays_are_flat_row_major_lists_that_read_back_in_shape() -> None:
    contour = _contour()
    obj = json.loads(encode_json(contour))
    assert obj["vertices"] == contour.vertices.reshape(-1).tolist()  # u0, v0, u1, v1, ...
    assert obj["_arrays"]["vertices"] == {"dtype": "<f8", "shape": [4, 2]}
    assert np.array_equal(decode_json(Contour, encode_json(contour)).vertices, contour.vertices)
    nested = json.dumps({**obj, "vertices": contour.vertices.tolist()}).encode()
    assert np.array_equal(decode_json(Contour, nested).vertices, contour.vertices)  # older files
