"""A recorded pick-up read with the official MCAP and Foxglove classes, against what it produced."""

from __future__ import annotations

import json
from itertools import accumulate
from pathlib import Path

import jsonschema
import numpy as np
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory
from scipy.spatial.transform import Rotation

from tests.recording.conftest import GRAPH, Run
from tests.recording.frame_tree import assert_one_tree


def _decoded(path: Path, topic: str) -> list[tuple[int, object]]:
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        return [
            (msg.log_time, proto) for _s, _c, msg, proto in reader.iter_decoded_messages([topic])
        ]


def _offset_ns(path: Path) -> int:
    """Wall-clock time minus the run's clock [ns] that the recording added to every time."""
    with open(path, "rb") as f:
        meta = {m.name: m.metadata for m in make_reader(f).iter_metadata()}
    return int(meta["umbra.run"]["clock_offset_ns"])


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
    # raw pixels do not compress: chunks are left uncompressed (LZ4 only cost time)
    assert {c.compression for c in summary.chunk_indexes} == {""}


def test_images_are_the_frames_the_camera_sent(pickup_run: Run) -> None:
    sent = pickup_run.sent["camera.image"]
    images = _decoded(pickup_run.recording, "/camera/image")
    off = _offset_ns(pickup_run.recording)
    assert len(images) == len(sent) == 44  # the first tick has no camera pose yet: no frame
    for (log_ns, raw), (now, sample) in zip(images, sent, strict=True):
        assert log_ns == round(now * 1e9) + off
        assert (raw.width, raw.height, raw.encoding) == (640, 480, "bgr8")
        assert raw.frame_id == "camera"
        assert raw.data == sample.pixels.tobytes()
        assert raw.timestamp.ToNanoseconds() == round(sample.stamp * 1e9) + off


def test_times_are_wall_clock_with_the_run_clock_kept(pickup_run: Run) -> None:
    """A viewer's time line shows the day of the run: every log time, publish time and
    timestamp is the run's clock plus one offset read when the recording started; the run's
    own stamps stay in JSON messages and in the offset."""
    import time

    off = _offset_ns(pickup_run.recording)
    run_started = pickup_run.recording.stat().st_mtime  # the file is younger than a minute
    assert abs(off / 1e9 - time.time()) < 600 and off / 1e9 < run_started + 1  # sim t=0 -> today
    with open(pickup_run.recording, "rb") as f:
        reader = make_reader(f)
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
        times = [(m.log_time, m.publish_time) for _s, _c, m in reader.iter_messages()]
    assert int(meta["umbra.run"]["t0_ns"]) == off  # the first tick (sim 0) on the wall line
    assert min(t for pair in times for t in pair) >= off
    assert max(t for pair in times for t in pair) <= off + 2_000_000_000  # a 1.5 s run
    _schema, twists = _json(pickup_run.recording, "/servo/twist")
    sent = pickup_run.sent["servo.twist"]
    assert [m["stamp"] for _t, m in twists] == [s.stamp for _n, s in sent]  # the run's clock


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
    assert ("base", "table") in pairs
    # the kinematics' recorded tool pose moves `tool`, the world's true camera pose `camera`:
    # the graph's static frames to them are left out, so each keeps one parent in a viewer
    assert not {c for _p, c in pairs} & {"tool", "camera"}


def _T(ft: object) -> np.ndarray:
    T = np.eye(4)
    q = ft.rotation  # type: ignore[attr-defined]
    T[:3, :3] = Rotation.from_quat([q.x, q.y, q.z, q.w]).as_matrix()
    t = ft.translation  # type: ignore[attr-defined]
    T[:3, 3] = [t.x, t.y, t.z]
    return T


def test_the_arm_link_frames_are_frame_transforms_at_the_measured_joints(
    pickup_run: Run,
) -> None:
    """What Foxglove's 3-D panel draws as the arm: a chain of DH frames, each in the one before,
    composing to the Puma 560's forward kinematics at the joint state the kinematics used."""
    from umbra.modules.arm.dh import puma560

    arm = puma560()
    sent = pickup_run.sent["kinematics.link_poses"]
    recorded = _decoded(pickup_run.recording, "/kinematics/link_poses")
    assert len(recorded) == len(sent) > 100
    states = pickup_run.sent["joints.joint_state"]
    tools = _decoded(pickup_run.recording, "/kinematics/tool_pose")
    assert len(tools) == len(recorded)
    moved = 0.0
    first_flange = None
    off = _offset_ns(pickup_run.recording)
    for (log_ns, fts), (now, poses), (_t, tool) in zip(recorded, sent, tools, strict=True):
        assert log_ns == round(now * 1e9) + off
        names = [t.child_frame_id for t in fts.transforms]
        assert names == ["link1", "link2", "link3", "link4", "link5", "flange"]
        parents = [t.parent_frame_id for t in fts.transforms]
        assert parents == ["base", "link1", "link2", "link3", "link4", "link5"]  # a chain
        T_base = np.stack(list(accumulate((_T(t) for t in fts.transforms), np.matmul)))
        assert np.allclose(T_base, poses.matrices, atol=1e-12)
        # the joint state the kinematics solved at: fed back, one of the two latest by this tick
        latest = [s.position for t, s in states if t <= now][-2:]
        assert any(np.allclose(T_base, arm.frames(q)[1:], atol=1e-9) for q in latest)
        T_flange_tool = np.eye(4)
        T_flange_tool[2, 3] = 0.14
        assert (tool.parent_frame_id, tool.child_frame_id) == ("base", "tool")
        assert np.allclose(_T(tool), T_base[-1] @ T_flange_tool, atol=1e-9)
        first_flange = T_base[-1] if first_flange is None else first_flange
        moved = max(moved, float(np.linalg.norm(T_base[-1][:3, 3] - first_flange[:3, 3])))
    assert moved > 0.01  # the arm moved: the frames are not one pose repeated


def test_every_frame_has_one_parent_and_hangs_from_the_base(pickup_run: Run) -> None:
    """A viewer keeps one transform tree: no frame with two parents, every frame reachable from
    the arm's base (the camera through the table, the links directly)."""
    frames = assert_one_tree(pickup_run.recording, root="base")
    assert {"camera", "patch", "table", "tool", "flange", "link1"} <= frames


def test_joint_rates_are_json_valid_against_their_schema_and_exact(pickup_run: Run) -> None:
    sent = pickup_run.sent["kinematics.joint_rates"]
    schema, messages = _json(pickup_run.recording, "/kinematics/joint_rates")
    assert schema["title"] == "umbra.JointRates"
    assert len(messages) == len(sent) > 100
    moving = 0
    validator = jsonschema.Draft202012Validator(schema)
    off = _offset_ns(pickup_run.recording)
    for (log_ns, obj), (now, sample) in zip(messages, sent, strict=True):
        validator.validate(obj)
        assert log_ns == round(now * 1e9) + off and obj["seq"] == sample.seq
        assert obj["rates"] == sample.rates.tolist() and tuple(obj["names"]) == sample.names
        moving += bool(np.any(sample.rates != 0))
    assert moving > 20  # the arm was moving: the numbers are not all zeros


def test_each_image_output_is_recorded_as_its_link_asks(tmp_path: Path) -> None:
    """`record.ports` chooses per output: the camera lossless (PNG), the drawn view as JPEG, the
    truth not at all; what is not named follows `record.images` (raw here: none left)."""
    import cv2

    from tests.recording.conftest import run_graph
    from umbra.runtime.graph.check import load_graph

    graph = tmp_path / "views.yaml"
    graph.write_text(
        "graph: views\nclock: sim\nseed: 1\n"
        "record: {images: raw, ports: {camera.image: png, view.overlay: jpeg, camera.truth: off}}\n"
        "modules:\n"
        "  camera: {type: DigiCam, rate: 10, params: {source: sim, width: 160, height: 120,"
        " fx: 140, fy: 140, u0: 80, v0: 60}}\n"
        "  view: {type: Overlay}\n  show: {type: Printer, params: {max_rate_hz: 0.1}}\n"
        "  truth: {type: Printer, params: {max_rate_hz: 0.1}}\n"
        "connections: [camera.image -> view.image, view.overlay -> show.value,"
        " camera.truth -> truth.value]\n"
    )
    watched = [("camera", "image"), ("view", "overlay")]
    run = run_graph(load_graph(graph), tmp_path / "run", duration=0.5, watched=watched)
    images = _decoded(run.recording, "/camera/image")
    views = _decoded(run.recording, "/view/overlay")
    assert len(images) == len(views) == 5
    for (_t, png), (_now, sample) in zip(images, run.sent["camera.image"], strict=True):
        assert png.format == "png"
        pixels = cv2.imdecode(np.frombuffer(png.data, np.uint8), cv2.IMREAD_UNCHANGED)
        assert np.array_equal(pixels, sample.pixels)  # lossless
    for (_t, jpeg), (_now, sample) in zip(views, run.sent["view.overlay"], strict=True):
        assert jpeg.format == "jpeg" and jpeg.data[:2] == b"\xff\xd8"
        pixels = cv2.imdecode(np.frombuffer(jpeg.data, np.uint8), cv2.IMREAD_UNCHANGED)
        error = np.abs(pixels.astype(int) - sample.pixels.astype(int))
        assert pixels.shape == sample.pixels.shape and 0 < error.mean() < 3.0  # lossy, close
    with open(run.recording, "rb") as f:
        summary = make_reader(f).get_summary()
    topics = {c.topic for c in summary.channels.values()}
    assert "/camera/truth" not in topics and "/camera/truth/annotations" not in topics
    assert {c.compression for c in summary.chunk_indexes} == {"lz4"}  # no raw image in it


def test_outputs_nobody_reads_are_recorded_but_images_only_when_named(tmp_path: Path) -> None:
    """As `ros2 bag record --all`: an output that feeds nothing is recorded (the camera's truth
    contour here); an image that feeds nothing (the drawn view) costs an encoding per frame and
    is recorded only when `record.ports` names it."""
    from tests.recording.conftest import run_graph
    from umbra.runtime.graph.check import load_graph

    def topics(record: str) -> set[str]:
        graph = tmp_path / f"{len(record)}.yaml"
        graph.write_text(
            f"graph: quiet\nclock: sim\nseed: 1\nrecord: {record}\n"
            "modules:\n"
            "  camera: {type: DigiCam, rate: 10, params: {source: sim, width: 160, height: 120,"
            " fx: 140, fy: 140, u0: 80, v0: 60}}\n"
            "  view: {type: Overlay}\n"
            "connections: [camera.image -> view.image]\n"
        )
        out = tmp_path / f"run{len(record)}"
        run = run_graph(load_graph(graph), out, duration=0.5, watched=[])
        with open(run.recording, "rb") as f:
            summary = make_reader(f).get_summary()
            counts = summary.statistics.channel_message_counts
        return {c.topic for i, c in summary.channels.items() if counts.get(i)}

    unnamed = topics("{images: raw}")
    assert {"/camera/image", "/camera/truth"} <= unnamed and "/view/overlay" not in unnamed
    named = topics("{images: raw, ports: {view.overlay: jpeg}}")
    assert {"/camera/image", "/camera/truth", "/view/overlay"} <= named


def test_every_json_channel_is_one_the_viewers_read_and_the_errors_plot(pickup_run: Run) -> None:
    from tests.recording.viewer_rules import viewer_datatypes

    with open(pickup_run.recording, "rb") as f:
        summary = make_reader(f).get_summary()
    json_topics = []
    for channel in summary.channels.values():
        schema = summary.schemas[channel.schema_id]
        if schema.encoding == "jsonschema":
            viewer_datatypes(json.loads(schema.data), schema.name)  # raises where a viewer would
            json_topics.append(channel.topic)
    assert {"/servo/status", "/servo/twist"} <= set(json_topics)
    assert "/joints/joint_state" not in json_topics  # foxglove.JointStates
    sent = pickup_run.sent.get("servo.twist")
    _schema, twists = _json(pickup_run.recording, "/servo/twist")
    assert [m["vector"][2] for _t, m in twists] == [s.vector[2] for _now, s in sent]
    _schema, statuses = _json(pickup_run.recording, "/servo/status")
    z = [m["values"]["error_z"] for _t, m in statuses if "error_z" in m["values"]]
    assert len(z) > 20 and z[-1] < z[0] - 0.04  # /servo/status.values.error_z: the approach


def test_joint_states_are_foxglove_joint_states_of_the_measured_joints(pickup_run: Run) -> None:
    sent = pickup_run.sent["joints.joint_state"]
    recorded = _decoded(pickup_run.recording, "/joints/joint_state")
    assert len(recorded) == len(sent) > 100
    off = _offset_ns(pickup_run.recording)
    for (_log, js), (_now, state) in zip(recorded, sent, strict=True):
        assert type(js).__name__ == "JointStates"  # decoded by its own schema
        assert [j.name for j in js.joints] == [*state.names, "gripper"]
        assert [j.position for j in js.joints] == [*state.position.tolist(), state.gripper]
        assert js.timestamp.ToNanoseconds() == round(state.stamp * 1e9) + off
