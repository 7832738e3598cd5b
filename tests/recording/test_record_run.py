"""A recorded pick-up read with the official MCAP and Foxglove classes, against what it produced."""

from __future__ import annotations

import json
from pathlib import Path

import jsonschema
import numpy as np
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory
from scipy.spatial.transform import Rotation

from tests.recording.conftest import GRAPH, Run


def _decoded(path: Path, topic: str) -> list[tuple[int, object]]:
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        return [
            (msg.log_time, proto) for _s, _c, msg, proto in reader.iter_decoded_messages([topic])
        ]


def _json(path: Path, topic: str) -> tuple[dict, list[tuple[int, dict]]]:
    with open(path, "rb") as f:
        reader = make_reader(f)
        items = list(reader.iter_messages([topic]))
    schema = json.loads(items[0][0].data)
    return schema, [(m.log_time, json.loads(m.data)) for _s, _c, m in items]


def test_every_channel_has_a_schema_and_the_file_says_what_made_it(pickup_run: Run) -> None:
    with open(pickup_run.recording, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None  # finished: index and summary written
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
        attachments = {a.name: a.data for a in reader.iter_attachments()}
    for channel in summary.channels.values():
        schema = summary.schemas[channel.schema_id]
        assert schema.name and schema.encoding in ("protobuf", "jsonschema") and schema.data
    topics = {c.topic for c in summary.channels.values()}
    assert {"/camera/image", "/snake/contour", "/snake/contour/annotations"} <= topics
    assert {"/kinematics/joint_rates", "/register/twist", "/tf_static"} <= topics
    assert meta["umbra.run"]["graph"] == "pickup_small" and meta["umbra.run"]["clock"] == "sim"
    assert json.loads(meta["umbra.parameters"]["servo"])["standoff"] == 0.14
    assert "mcap" in meta["umbra.versions"] and "python" in meta["umbra.versions"]
    assert meta["umbra.recording"]["dropped"] == "0"
    assert json.loads(meta["umbra.frames"]["flange->tool"])[2][3] == 0.14
    assert attachments["graph.yaml"] == GRAPH.read_bytes()


def test_images_are_the_frames_the_camera_sent(pickup_run: Run) -> None:
    sent = pickup_run.sent["camera.image"]
    images = _decoded(pickup_run.recording, "/camera/image")
    assert len(images) == len(sent) == 45
    for (log_ns, raw), (now, sample) in zip(images, sent, strict=True):
        assert log_ns == round(now * 1e9)
        assert (raw.width, raw.height, raw.encoding) == (640, 480, "bgr8")
        assert raw.frame_id == "camera"
        assert raw.data == sample.pixels.tobytes()
        assert raw.timestamp.ToNanoseconds() == round(sample.stamp * 1e9)


def test_snake_annotations_are_the_contours_drawn_on_their_own_frames(pickup_run: Run) -> None:
    sent = pickup_run.sent["snake.contour"]
    annotations = _decoded(pickup_run.recording, "/snake/contour/annotations")
    image_times = {
        raw.timestamp.ToNanoseconds() for _t, raw in _decoded(pickup_run.recording, "/camera/image")
    }
    assert len(annotations) == len(sent)
    tracked = 0
    for (_log, ann), (_now, contour) in zip(annotations, sent, strict=True):
        assert ann.texts[0].text.startswith(contour.status)
        if contour.status != "tracking":
            continue
        tracked += 1
        outline = ann.points[0]
        points = np.array([(p.x, p.y) for p in outline.points])
        assert np.array_equal(points, contour.vertices)
        assert outline.timestamp.ToNanoseconds() in image_times  # drawn on the frame it came from
    assert tracked >= 20  # the snake locked on and tracked for most of the run


def test_camera_poses_are_frame_transforms_of_the_world(pickup_run: Run) -> None:
    sent = pickup_run.sent["world.camera_pose"]
    transforms = _decoded(pickup_run.recording, "/world/camera_pose")
    assert len(transforms) == len(sent) > 100
    for (_log, ft), (_now, pose) in zip(transforms, sent, strict=True):
        assert (ft.parent_frame_id, ft.child_frame_id) == (pose.parent, pose.child)
        t = [ft.translation.x, ft.translation.y, ft.translation.z]
        assert np.allclose(t, pose.matrix[:3, 3], atol=1e-12)
        q = [ft.rotation.x, ft.rotation.y, ft.rotation.z, ft.rotation.w]
        assert np.allclose(Rotation.from_quat(q).as_matrix(), pose.matrix[:3, :3], atol=1e-12)
    with open(pickup_run.recording, "rb") as f:
        reader = make_reader(f)
        ((_s, _c, msg),) = reader.iter_messages(["/tf_static"])
    static = FrameTransforms.FromString(msg.data)
    pairs = {(t.parent_frame_id, t.child_frame_id) for t in static.transforms}
    assert {("base", "table"), ("flange", "tool")} <= pairs


def test_joint_rates_are_json_valid_against_their_schema_and_exact(pickup_run: Run) -> None:
    sent = pickup_run.sent["kinematics.joint_rates"]
    schema, messages = _json(pickup_run.recording, "/kinematics/joint_rates")
    assert schema["title"] == "umbra.JointRates"
    assert len(messages) == len(sent) > 100
    moving = 0
    validator = jsonschema.Draft202012Validator(schema)
    for (log_ns, obj), (now, sample) in zip(messages, sent, strict=True):
        validator.validate(obj)
        assert log_ns == round(now * 1e9) and obj["seq"] == sample.seq
        assert obj["rates"] == sample.rates.tolist() and tuple(obj["names"]) == sample.names
        moving += bool(np.any(sample.rates != 0))
    assert moving > 20  # the arm was moving: the numbers are not all zeros
