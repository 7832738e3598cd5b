"""A running pick-up served live, read by Foxglove's own npm client (``@foxglove/ws-protocol``,
protobuf decoded by protobufjs from each channel's schema): every channel, the recordings' schemas,
topics and frames, wall-clock times, parameters visible and not changeable."""

from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from tests.live.helpers import (
    REPO,
    LiveRun,
    install_client,
    needs_node,
    run_client,
    run_tune,
    wait_joined,
)
from umbra.runtime.graph.check import load_graph
from umbra.runtime.recording.encoders import channel_encodings
from umbra.runtime.recording.tap import topic_of

# whole runs of umbra in subprocesses, seconds each: in CI with -m slow (a short default run)
pytestmark = pytest.mark.slow

GRAPH = REPO / "graphs" / "tool_pickup.yaml"
#: A safety parameter (of REG_VEL, a guard), a tunable one out of its bounds, then within them.
TUNING = [
    {"at": 0.2, "name": "register.timeout", "value": 1.0},
    {"at": 0.4, "name": "snake.tension", "value": 3.0},
    {"at": 0.6, "name": "snake.tension", "value": 0.25},
]


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return install_client(tmp_path_factory.mktemp("npm"))


def _expected_channels() -> dict[str, str]:
    """Topic -> schema name of every channel the run should advertise (the recorder's table)."""
    plan = load_graph(str(GRAPH))
    found = {"/tf_static": "foxglove.FrameTransforms"}
    for module, mplan in plan.modules.items():
        for port, info in mplan.outputs.items():
            images = "jpeg"
            for enc in channel_encodings(info.msg_type, images):
                found[topic_of(module, port) + enc.suffix] = enc.schema_name
    return found


@needs_node
def test_the_npm_client_decodes_every_channel_of_a_running_pickup(
    client: Path, tmp_path: Path
) -> None:
    args = ("--single-process", "--clock", "real", "--duration", "30")
    run = LiveRun(str(GRAPH), tmp_path / "run", *args)
    try:
        time.sleep(2.0)  # the pick-up under way (it ends when the tool is grasped)
        with ThreadPoolExecutor(1) as pool:  # a second viewer, tuning, at the same time
            tuning = pool.submit(run_tune, client.parent / "tune.js", run.url, 8.0, "", TUNING)
            report = run_client(client, run.url, 6.0)
            tuned = tuning.result()
    finally:
        run.stop()
    assert report.get("error") is None, report.get("error")
    advertised = {t: c["schemaName"] for t, c in report["channels"].items()}
    assert advertised == _expected_channels()  # one table for the file and the live server
    topics = report["topics"]
    assert all(t["errors"] == 0 for t in topics.values()), {
        k: v.get("error") for k, v in topics.items() if v["errors"]
    }
    # every output the pick-up produces in these seconds arrived and decoded
    producing = {
        "/camera/image", "/camera/truth/annotations", "/snake/contour/annotations",
        "/joints/joint_state", "/kinematics/link_poses", "/kinematics/tool_pose",
        "/kinematics/joint_rates", "/servo/twist", "/servo/status", "/world/camera_pose",
        "/tf_static", "/view/overlay",
    }  # fmt: skip
    assert producing <= {t for t, v in topics.items() if v["count"] > 0}
    assert topics["/joints/joint_state"]["count"] > 20

    image = topics["/camera/image"]["first"]
    assert image["format"] == "jpeg" and image["frame_id"] == "camera"
    annotation = topics["/snake/contour/annotations"]["first"]
    assert annotation["texts"][0]["text"]  # the snake's status on its image (an outline once
    # it tracks: before the operator's click the first one may have none)
    joints = topics["/joints/joint_state"]["first"]["joints"]
    assert [j["name"] for j in joints] == ["j1", "j2", "j3", "j4", "j5", "j6", "gripper"]
    links = topics["/kinematics/link_poses"]["first"]["transforms"]
    parents = [t["parent_frame_id"] for t in links]
    assert parents == ["base", "link1", "link2", "link3", "link4", "link5"]  # a chain
    static = {
        t["child_frame_id"]: t["parent_frame_id"]
        for t in topics["/tf_static"]["first"]["transforms"]
    }
    assert static["table"] == "base" and static["tool"] == "flange"

    # the time line is wall-clock: log times and the messages' own stamps are today's
    now_ns = time.time() * 1e9
    for name in ("/camera/image", "/joints/joint_state", "/servo/twist"):
        log_ns = [int(t) for t in topics[name]["logTimeNs"]]
        assert all(abs(t - now_ns) < 120e9 for t in log_ns), name
    stamp = joints_stamp = topics["/joints/joint_state"]["first"]["timestamp"]
    assert abs(int(stamp["seconds"]) - time.time()) < 120, joints_stamp
    assert 0 < topics["/servo/twist"]["first"]["stamp"] < 1e7  # JSON keeps the run's clock

    # parameters: visible, and a client's attempt to change one changes nothing
    assert report["parameters"] > 50
    tried = report["triedSet"]
    assert report["afterSet"] == [{"name": tried["name"], "value": tried["value"]}]
    assert f"asked to set {tried['name']} = " in run.text() and "refused" in run.text()

    # a safety parameter and a value out of its bounds are refused, with the reason; a tunable
    # one within its bounds is changed between two of the snake's steps and logged
    assert tuned["answers"]["set0"] == [{"name": "register.timeout", "value": 0.1}]
    assert tuned["answers"]["set1"] == [{"name": "snake.tension", "value": 0.2}]
    assert tuned["answers"]["set2"] == [{"name": "snake.tension", "value": 0.25}]
    said = [s["message"] for s in tuned["statuses"]]
    assert len(said) == 2 and "safety guard (REG_VEL)" in said[0], said
    assert "snake.tension" in said[1] and "less than or equal to 0.5" in said[1], said
    assert "param snake.tension 0.2 -> 0.25 by foxglove viewer" in run.text()


@needs_node
def test_a_split_pickup_is_served_from_every_process_it_runs(client: Path, tmp_path: Path) -> None:
    """Three processes (vision `umbra`, the operator's page `ui`, the servo side `smart`): the
    live server in the `umbra` command observes each on zenoh (--publish-all) and serves them."""
    # the grasp's verdict would end the run ~15 s in, perhaps while the client still reads
    run = LiveRun(str(GRAPH), tmp_path / "run", "--duration", "40", "--set", "world.end_run=false")
    try:
        wait_joined(run)  # the processes up, linked, and their samples reaching the live server
        time.sleep(1.0)
        report = run_client(client, run.url, 6.0)
    finally:
        run.stop()
    topics = report["topics"]
    assert all(t["errors"] == 0 for t in topics.values())
    seen = {t for t, v in topics.items() if v["count"] > 0}
    # vision (umbra), the arm and its joints (smart); the page (ui) sends only on events
    assert {"/camera/image", "/camera/truth/annotations"} <= seen
    assert {"/joints/joint_state", "/kinematics/link_poses", "/register/twist"} <= seen
    assert "/console/presence" in report["channels"]
    # a stream from the servo side (100 Hz there): the live server sends the newest sample and
    # drops the rest when it falls behind, so a loaded machine delivers fewer than 600 in 6 s
    # (15 a second measured under a browser test's load; the rate is bench_live's figure)
    assert topics["/joints/joint_state"]["count"] >= 20
    joints = topics["/joints/joint_state"]["first"]["joints"]
    assert [j["name"] for j in joints][-1] == "gripper"
