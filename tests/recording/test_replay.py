"""A recorded pick-up replayed into the graph: same parameters, same commands, sample for sample."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.recording.conftest import GRAPH, Run, run_graph
from umbra.connectors.errors import CheckFailed, UserError
from umbra.connectors.messages import Scalar
from umbra.runtime.cli.main import main
from umbra.runtime.graph.check import load_graph
from umbra.runtime.recording.replay import plan_replay
from umbra.runtime.recording.writer import RecordingFile

COMMANDS = ["servo.twist", "register.twist", "kinematics.joint_rates", "snake.contour"]


def _same(a: Any, b: Any) -> bool:
    if type(a) is not type(b) or a.stamp != b.stamp or a.seq != b.seq:
        return False
    for name in a.__struct_fields__:
        va, vb = getattr(a, name), getattr(b, name)
        if isinstance(va, np.ndarray):
            if not np.array_equal(va, vb):
                return False
        elif va != vb:
            return False
    return True


def _replayed(pickup_run: Run, out: Path, **overrides: dict[str, Any]) -> Run:
    plan = load_graph(GRAPH, overrides=overrides or None)
    feed, names = plan_replay(plan, pickup_run.recording, None, "sim")
    assert names == ["camera"]  # the default: the modules whose recorded outputs are images
    run = run_graph(plan, out)
    assert feed.sent == len(pickup_run.sent["camera.image"]) + 44  # images and truth contours
    return run


def test_replay_with_the_same_parameters_reproduces_every_command(
    pickup_run: Run, tmp_path: Path
) -> None:
    replay = _replayed(pickup_run, tmp_path / "replay")
    for key in COMMANDS:
        original, again = pickup_run.sent[key], replay.sent[key]
        assert len(again) == len(original) > 40, key
        for (t0, a), (t1, b) in zip(original, again, strict=True):
            assert t0 == t1 and _same(a, b), (key, t0, a, b)
    moving = [s for _t, s in pickup_run.sent["kinematics.joint_rates"] if np.any(s.rates)]
    assert len(moving) > 20  # there was an approach to reproduce, not only zeros


def test_replay_with_a_lower_servo_speed_limit_changes_the_commands_only(
    pickup_run: Run, tmp_path: Path
) -> None:
    replay = _replayed(pickup_run, tmp_path / "slower", servo={"max_linear": 0.025})
    snake = zip(pickup_run.sent["snake.contour"], replay.sent["snake.contour"], strict=True)
    assert all(_same(a, b) for (_t, a), (_u, b) in snake)  # the same recorded images
    original = [s.vector for _t, s in pickup_run.sent["servo.twist"]]
    slower = [s.vector for _t, s in replay.sent["servo.twist"]]
    moving = [i for i, v in enumerate(original) if np.linalg.norm(v[:3]) > 1e-4]
    assert len(moving) > 10
    ratio = [np.linalg.norm(slower[i][:3]) / np.linalg.norm(original[i][:3]) for i in moving]
    assert np.median(ratio) == pytest.approx(0.5, abs=0.05)  # the approach runs at the limit


def _cli(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str]:
    code = main(list(args))
    return code, capsys.readouterr().err


def test_replay_refuses_a_graph_whose_frames_differ(
    pickup_run: Run, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    graph = tmp_path / "other_frame.yaml"
    graph.write_text(
        GRAPH.read_text()
        .replace("world_frame: table,", "world_frame: table, camera_frame: wrist,")
        .replace("  tool->camera:", "  camera->wrist: {}\n  tool->camera:")
    )
    code, err = _cli(
        capsys, "replay", str(pickup_run.recording), str(graph), "--out", str(tmp_path / "o")
    )
    assert code == 2 and "Traceback" not in err
    assert f"{graph}:" in err and "error: replay: output `camera.image` is in frame `wrist`" in err
    assert "`camera`" in err and not (tmp_path / "o").exists()  # refused before anything ran


def test_replay_refuses_unknown_guard_and_unrecorded_modules(
    pickup_run: Run, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    rec, out = str(pickup_run.recording), str(tmp_path / "o")
    code, err = _cli(capsys, "replay", rec, str(GRAPH), "--replace", "camra", "--out", out)
    assert code == 2 and "no module `camra` to replace" in err and "camera" in err
    code, err = _cli(capsys, "replay", rec, str(GRAPH), "--replace", "register", "--out", out)
    assert code == 2 and "`register` is a safety guard" in err
    code, err = _cli(capsys, "replay", rec, str(GRAPH), "--replace", "kinematics", "--out", out)
    assert code == 2 and "guarded input `joints.rates`" in err
    assert not Path(out).exists()


def test_replay_refuses_outputs_that_were_not_recorded_or_of_another_type(
    tmp_path: Path,
) -> None:
    recorded = tmp_path / "counter.yaml"
    recorded.write_text(
        "graph: counter\nclock: sim\nrecord: {ports: {c.count: off}}\nmodules:\n"
        "  c: {type: Counter, rate: 10}\n  g: {type: Gain, params: {gain: 2}}\n"
        "  t: {type: Constant, rate: 10}\n  g2: {type: Gain}\n"
        "connections: [c.count -> g.input, t.output -> g2.input]\n"
    )
    run = run_graph(load_graph(recorded), tmp_path / "run", duration=1.0, watched=[])
    rec = run.out / "recording.mcap"
    with pytest.raises(CheckFailed) as err:
        plan_replay(load_graph(recorded), rec, ["c"], "sim")
    assert f"{recorded}:5:3: error: replay: output `c.count` (Scalar) feeds g.input" in str(
        err.value
    )
    assert "has no `/c/count`" in str(err.value)
    other = tmp_path / "other.yaml"
    other.write_text(
        "graph: other\nclock: sim\nmodules:\n  t: {type: TwistSource, rate: 10}\n"
        "  p: {type: Printer}\nconnections: [t.twist -> p.value]\n"
    )
    scalars = tmp_path / "scalars.mcap"  # an older graph's `t.twist` carried numbers
    writer = RecordingFile(scalars, blocking=True)
    writer.declare("/t/twist", Scalar, {"umbra.port": "t.twist"})
    writer.offer("/t/twist", Scalar(value=1.0, stamp=0.0, seq=1), 0.0)
    writer.close()
    with pytest.raises(
        CheckFailed, match="carries Twist, the recording's `/t/twist` carries Scalar"
    ):
        plan_replay(load_graph(other), scalars, ["t"], "sim")
    with pytest.raises(UserError, match="no module to replace"):
        plan_replay(load_graph(recorded), rec, None, "sim")


def test_a_recorded_output_nobody_reads_is_checked_before_it_is_replayed(tmp_path: Path) -> None:
    """A replaced module also sends its recorded outputs that feed nothing (so a re-record holds
    them again): they are checked as the connected ones are, before anything runs."""
    other = tmp_path / "other.yaml"
    other.write_text(
        "graph: other\nclock: sim\nmodules:\n  c: {type: Counter, rate: 10}\n"
        "  t: {type: TwistSource, rate: 10}\n  p: {type: Printer}\n"
        "connections: [c.count -> p.value]\n"
    )
    wrong = tmp_path / "wrong.mcap"  # `t.twist` feeds nothing here, and was recorded as numbers
    writer = RecordingFile(wrong, blocking=True)
    writer.declare("/c/count", Scalar, {"umbra.port": "c.count"})
    writer.declare("/t/twist", Scalar, {"umbra.port": "t.twist"})
    writer.offer("/c/count", Scalar(value=1.0, stamp=0.0, seq=1), 0.0)
    writer.offer("/t/twist", Scalar(value=1.0, stamp=0.0, seq=1), 0.0)
    writer.close()
    with pytest.raises(
        CheckFailed,
        match=re.escape("`t.twist` carries Twist, the recording's `/t/twist` carries Scalar"),
    ):
        plan_replay(load_graph(other), wrong, ["c", "t"], "sim")
    _feed, names = plan_replay(load_graph(other), wrong, ["c"], "sim")  # `t` not replaced: fine
    assert names == ["c"]


def test_the_default_replay_stands_in_for_cameras_not_for_a_drawn_view(tmp_path: Path) -> None:
    """An image nobody reads is recorded when `record.ports` names it (the Overlay's drawn view),
    but the module that drew it is not a camera: replay re-runs it on the replayed images."""
    graph = tmp_path / "view.yaml"
    graph.write_text(
        "graph: view\nclock: sim\nseed: 1\nrecord: {images: raw, ports: {view.overlay: png}}\n"
        "modules:\n"
        "  camera: {type: DigiCam, rate: 10, params: {source: sim, width: 160, height: 120,"
        " fx: 140, fy: 140, u0: 80, v0: 60}}\n"
        "  view: {type: Overlay}\n"
        "connections: [camera.image -> view.image]\n"
    )
    run = run_graph(load_graph(graph), tmp_path / "run", duration=0.5, watched=[])
    _feed, names = plan_replay(load_graph(graph), run.recording, None, "sim")
    assert names == ["camera"]


def test_replay_of_a_counter_sends_the_recorded_values_at_their_times(tmp_path: Path) -> None:
    graph = tmp_path / "counter.yaml"
    graph.write_text(
        "graph: counter\nclock: sim\nrecord: true\nmodules:\n"
        "  c: {type: Counter, rate: 20, params: {start: 5}}\n  g: {type: Gain, params: {gain: 2}}\n"
        "connections: [c.count -> g.input]\n"
    )
    watched = [("c", "count"), ("g", "output")]
    run = run_graph(load_graph(graph), tmp_path / "run", duration=1.0, watched=watched)
    plan = load_graph(graph, overrides={"g": {"gain": 3.0}})
    plan_replay(plan, run.out / "recording.mcap", ["c"], "sim")
    again = run_graph(plan, tmp_path / "replay", duration=2.0, watched=watched)
    assert [(t, s.value) for t, s in again.sent["c.count"]] == [
        (t, s.value) for t, s in run.sent["c.count"]
    ]
    assert [s.value for _t, s in again.sent["g.output"]] == [
        3 * s.value for _t, s in run.sent["c.count"]
    ]
    assert again.result.reason.startswith("replay: the recording ends at 0.950 s")


def test_replay_on_the_real_clock_keeps_the_recorded_pace(tmp_path: Path) -> None:
    from umbra.runtime.scheduler import Scheduler, SchedulerOptions

    graph = tmp_path / "counter.yaml"
    graph.write_text(
        "graph: counter\nclock: sim\nrecord: true\nmodules:\n"
        "  c: {type: Counter, rate: 20}\n  g: {type: Gain}\nconnections: [c.count -> g.input]\n"
    )
    run = run_graph(load_graph(graph), tmp_path / "run", duration=0.5, watched=[("c", "count")])
    plan = load_graph(graph)
    plan.spec.record.enabled = False
    plan_replay(plan, run.out / "recording.mcap", ["c"], "real")
    scheduler = Scheduler(plan, SchedulerOptions(clock="real", output_dir=tmp_path / "real"))
    got: list[tuple[float, float]] = []
    scheduler.modules["c"].outputs["count"].sinks.append(lambda s, now: got.append((now, s.value)))
    result = scheduler.run()
    assert [v for _t, v in got] == [s.value for _t, s in run.sent["c.count"]]
    # recorded over 0.45 s: at the recorded pace the replay cannot be done sooner
    assert got[-1][0] - got[0][0] >= 0.45 - 1e-3
    assert result.reason.startswith("replay: the recording ends")


def test_the_replay_command_runs_and_records_the_replay(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from umbra.runtime.recording.samples import iter_samples

    graph = tmp_path / "counter.yaml"
    graph.write_text(
        "graph: counter\nclock: sim\nmodules:\n  c: {type: Counter, rate: 10}\n"
        "  g: {type: Gain, params: {gain: 2}}\n  p: {type: Printer}\n"
        "connections: [c.count -> g.input, g.output -> p.value]\n"
    )
    first, again = tmp_path / "first", tmp_path / "again"
    assert main(["run", str(graph), "--duration", "1", "--record", "--out", str(first)]) == 0
    rec = str(first / "recording.mcap")
    args = ["--replace", "c", "--set", "g.gain=5", "--record", "--out", str(again)]
    code = main(["replay", rec, str(graph), *args])
    err = capsys.readouterr().err
    assert code == 0, err
    assert "umbra replay: c replayed from" in err
    # the recorded run's ticks (0 .. 0.9 s) and not one more
    assert "duration 0.9 s reached after 10 ticks" in err
    counts = [s.message.value for s in iter_samples(again / "recording.mcap", ["/c/count"])]
    gained = [s.message.value for s in iter_samples(again / "recording.mcap", ["/g/output"])]
    assert counts == [float(n) for n in range(10)] and gained == [5.0 * c for c in counts]


def _unshifted(proto: Any, off: int) -> None:
    """Take ``off`` [ns] from every ``google.protobuf.Timestamp`` inside ``proto`` (in place)."""
    for field, value in proto.ListFields():
        if field.message_type is None:
            continue
        items = value if hasattr(value, "add") else [value]  # repeated, or one message
        for item in items:
            if field.message_type.full_name == "google.protobuf.Timestamp":
                item.FromNanoseconds(item.ToNanoseconds() - off)
            else:
                _unshifted(item, off)


def _messages(path: Path) -> dict[str, list[tuple[int, int, int, bytes]]]:
    """Each topic's messages, times on the run's clock: the file's wall-clock offset taken from
    log and publish times and from the Foxglove messages' own timestamps."""
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory

    found: dict[str, list[tuple[int, int, int, bytes]]] = {}
    with open(path, "rb") as f:
        reader = make_reader(f)
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
        off = int(meta["umbra.run"]["clock_offset_ns"])
        factory = DecoderFactory()
        for schema, channel, msg in reader.iter_messages(log_time_order=False):
            data = msg.data
            if schema is not None and schema.encoding == "protobuf":
                proto = factory.decoder_for("protobuf", schema)(data)
                _unshifted(proto, off)
                data = proto.SerializeToString()
            found.setdefault(channel.topic, []).append(
                (msg.log_time - off, msg.publish_time - off, msg.sequence, data)
            )
    return found


def test_the_replay_command_recorded_again_gives_the_same_file_message_for_message(
    pickup_run: Run, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`umbra replay` of the camera, recorded with the same settings: every channel of the
    replay's recording (commands, joint states, poses, contours, annotations) holds the same
    messages, byte for byte, at the same times on the run's clock (each file has its own
    wall-clock offset), as the recorded run's: no sample more or less."""
    out = tmp_path / "again"
    args = ["--record", "--record-images", "raw", "--out", str(out), "--quiet"]
    code, err = _cli(capsys, "replay", str(pickup_run.recording), str(GRAPH), *args)
    assert code == pickup_run.result.exit_code, err  # the same outcome (World's verdict) too
    original, again = _messages(pickup_run.recording), _messages(out / "recording.mcap")
    assert set(again) == set(original)
    for topic, messages in original.items():
        assert again[topic] == messages, topic
    assert len(original["/servo/twist"]) == 44 and len(original["/register/twist"]) == 151
