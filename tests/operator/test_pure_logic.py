"""The console's pure logic: messages, control, dead-man jog, actions, what the page draws."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tests.operator.helpers import rectangle_contour
from umbra.connectors.access.secret import is_loopback, resolve_token, token_matches
from umbra.connectors.commands import SeedShape
from umbra.connectors.messages import JointState
from umbra.connectors.states import (
    GuardReason,
    GuardStage,
    GuardState,
    ServoReason,
    ServoStage,
    ServoState,
)
from umbra.modules.geometry.transforms import twist_tool_from_camera
from umbra.modules.operator.actions import (
    FrameHistory,
    Refused,
    ShownFrame,
    box_seed,
    check_snake_healthy,
    point_seed,
)
from umbra.modules.operator.control import ControlArbiter
from umbra.modules.operator.jog import DeadMan, JogLimits, JogStop, jog_twist
from umbra.modules.operator.protocol import MessageChecker, ProtocolError, ReplayedMessage
from umbra.modules.operator.view_state import joints_view, overlay, servo_view, zero_banner
from umbra.modules.vision.sanity import SanityLimits


def _msg(**fields: object) -> str:
    return json.dumps({"session": "abc", **fields})


def test_messages_are_checked_for_shape_session_and_order() -> None:
    c = MessageChecker("abc")
    m = c.check(_msg(seq=1, type="click", u=10.5, v=20, frame=7))
    assert (m.type, m.seq, m.fields) == ("click", 1, {"u": 10.5, "v": 20, "frame": 7})
    cases = [
        ("x" * 5000, "expected at most 4096 bytes, found 5000"),
        ("[1, 2]", "expected a JSON object, found list"),
        (_msg(seq=2, type="fly"), "expected type one of"),
        (_msg(seq=1, type="take"), "replayed message: expected seq > 1, found 1"),
        (
            json.dumps({"session": "zzz", "seq": 9, "type": "take"}),
            "replayed message: expected this page's session",
        ),
        (_msg(seq=3, type="click", u="1", v=2, frame=1), "expected u a finite number, found '1'"),
        (_msg(seq=3, type="click", u=1e999, v=2, frame=1), "expected u a finite number"),
        (_msg(seq=3, type="click", u=1, v=2, frame=-1), "expected frame a non-negative integer"),
        (_msg(seq=3, type="action", action="dance"), "expected one of ['start', 'pause'"),
        (_msg(seq=3, type="jog", held=1, axes=[0, 0, 0, 0], jog_frame="tool", speed=1), "held"),
        (
            _msg(
                seq=3, type="jog", held=True, axes=[0, 0, 0, 0], jog_frame="world", speed=1, frame=1
            ),
            "expected jog_frame one of ['tool', 'camera'], found 'world'",
        ),
        (
            _msg(
                seq=3, type="jog", held=True, axes=[0, 0, 0, 0], jog_frame="tool", speed=2, frame=1
            ),
            "expected speed in [0, 1], found 2",
        ),
    ]
    for raw, expected in cases:
        with pytest.raises(ProtocolError, match=None) as info:
            c.check(raw)
        assert expected in str(info.value), (raw[:60], str(info.value))
        # a replay is told by its type (counted apart), not by its words
        assert isinstance(info.value, ReplayedMessage) == expected.startswith("replayed")
    assert c.last_seq == 1  # refused messages do not advance the order
    assert c.check(_msg(seq=5, type="take")).seq == 5


def test_one_operator_holds_control_and_the_rest_are_refused_and_counted() -> None:
    a = ControlArbiter()
    a.join("s1", "alice")
    a.join("s2", "bob")
    assert not a.may_command("s1", "click").ok
    assert a.take("s1").ok and a.person_acted
    refused = a.take("s2")
    assert not refused.ok and "alice holds control" in refused.message
    assert a.may_command("s1", "resume").ok
    assert not a.may_command("s2", "abort").ok
    assert not a.release("s2").ok
    assert a.leave("s1") and a.holder is None  # a disconnect frees control
    assert a.take("s2").ok and a.holder_name() == "bob"
    assert a.refused == 4


def test_dead_man_drops_the_jog_on_release_silence_and_disconnect() -> None:
    d = DeadMan(0.15)
    d.update("s1", True, [1, 0, 0, 0], 0.5, "camera", now=10.0)
    assert d.current(10.1) is not None
    assert d.current(10.16) is None and d.expired == 1  # keep-alives stopped: zero
    d.update("s1", True, [0, 0, 1, 0], 1.0, "tool", now=10.5)  # the late hold stays stopped
    assert d.current(10.51) is None and d.stopped["s1"].code == JogStop.SILENT_PAGE
    d.update("s1", False, [0, 0, 0, 0], 1.0, "tool", now=10.9)  # until released
    d.update("s1", True, [0, 0, 1, 0], 1.0, "tool", now=11.0)
    d.update("s2", False, [0, 0, 0, 0], 1.0, "tool", now=11.01)  # another page's release
    assert d.current(11.02) is not None
    d.update("s1", False, [0, 0, 1, 0], 1.0, "tool", now=11.05)
    assert d.current(11.06) is None
    d.update("s1", True, [0, 0, 0, 1], 1.0, "tool", now=12.0)
    d.release("s1")
    assert d.current(12.01) is None


def test_tool_frame_jog_is_moved_into_the_camera_frame() -> None:
    limits = JogLimits(linear=0.02, angular=0.2)
    T = np.eye(4)
    T[:3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]  # camera turned 90 deg about z
    T[:3, 3] = [0.05, 0.0, -0.12]
    cam = jog_twist([1, 0, 0, 0], 0.5, "camera", limits, T)
    assert cam.tolist() == [0.01, 0, 0, 0, 0, 0]
    tool_x = jog_twist([1, 0, 0, 0], 0.5, "tool", limits, T)
    # tool +x is camera -y for this mounting
    np.testing.assert_allclose(tool_x, [0, -0.01, 0, 0, 0, 0], atol=1e-12)
    roll = jog_twist([0, 0, 0, 1], 1.0, "tool", limits, T)
    # a roll about the tool axis moves the offset camera sideways: the lever arm is kept
    np.testing.assert_allclose(twist_tool_from_camera(T, roll), [0, 0, 0, 0, 0, 0.2], atol=1e-12)
    assert abs(roll[0]) + abs(roll[1]) > 0.009


def test_clicks_boxes_and_stale_pages() -> None:
    h = FrameHistory(keep=3)
    for seq in range(1, 6):
        h.add(ShownFrame(seq, stamp=seq * 0.1, width=640, height=480))
    frame = h.frame_for(5, now=0.55, max_age=0.1)
    point = point_seed(frame, 10, 470)
    assert point.shape == SeedShape.POINT and point.uv.tolist() == [10.0, 470.0]
    with pytest.raises(Refused, match=r"click outside the image: .* found \(640.0, 10.0\)"):
        point_seed(frame, 640, 10)
    with pytest.raises(Refused, match=r"is 0\.250 s old, expected at most 0\.100 s"):
        h.frame_for(3, now=0.55, max_age=0.1)
    with pytest.raises(Refused, match="frame 1\\) is no longer live"):
        h.frame_for(1, now=0.55, max_age=10)
    box = box_seed(frame, 300, 260, 200, 100)
    assert box.shape == SeedShape.BOX and box.uv.tolist() == [200.0, 100.0, 300.0, 260.0]
    assert box.problem() == ""
    with pytest.raises(Refused, match="box too small"):
        box_seed(frame, 10, 10, 12, 40)


def test_resume_needs_a_healthy_fresh_snake() -> None:
    ok = rectangle_contour()
    check_snake_healthy(ok, 0.05, 0.5, "resume")
    with pytest.raises(Refused, match=r"not healthy \(area jump\)"):
        check_snake_healthy(rectangle_contour("failed", "area jump"), 0.0, 0.5, "resume")
    with pytest.raises(Refused, match="found no contour yet"):
        check_snake_healthy(None, float("inf"), 0.5, "start")
    with pytest.raises(Refused, match=r"1\.20 s old"):
        check_snake_healthy(ok, 1.2, 0.5, "resume")


def test_overlay_has_the_snake_shapes_in_pixels() -> None:
    o = overlay(rectangle_contour(), SanityLimits())
    assert o is not None and len(o["points"]) == 16 and o["offending"] == [3, 4]
    cu, cv = o["centroid"]
    assert 330 < cu < 350 and 225 < cv < 235
    assert len(o["rectangle"]) == 4
    us = [p[0] for p in o["rectangle"]]
    assert min(us) < 300 and max(us) > 380  # the outer rectangle encloses the patch
    assert o["ellipse"]["rx"] < 40 and o["ellipse"]["ry"] < 30
    assert overlay(None, SanityLimits()) is None


def test_banner_errors_and_joints_for_the_page() -> None:
    errors = {"error_x": 0.0021, "error_roll": np.radians(2)}
    status = ServoState(stage=ServoStage.APPROACH, values=errors)
    assert servo_view(status)["errors"] == {"x": 2.1, "roll": 2.0}
    passing = GuardState(stage=GuardStage.PASSING, code=GuardReason.PASSING)
    assert zero_banner(status, passing) == ""
    guard = GuardState(
        stage=GuardStage.ZERO,
        code=GuardReason.WATCHDOG,
        reason="command is 0.300 s old (timeout 0.100 s)",
    )
    assert zero_banner(status, guard) == (
        "servo side at zero (REG_VEL): command is 0.300 s old (timeout 0.100 s)"
    )
    paused = ServoState(
        stage=ServoStage.PAUSED, message="paused by the operator", code=ServoReason.PAUSED
    )
    jogging = GuardState(stage=GuardStage.PASSING, code=GuardReason.PASSING, jog=True)
    assert zero_banner(paused, jogging) == ""
    assert zero_banner(paused, None) == "servo side at zero: paused by the operator"
    assist = ServoState(
        stage=ServoStage.ASSIST,
        assist=True,
        reason="snake failure: border",
        code=ServoReason.SNAKE_FAILED,
    )
    assert zero_banner(assist, None) == (
        "servo side at zero: vsServo asks for the operator: snake failure: border"
    )
    waiting = ServoState(
        stage=ServoStage.ACQUIRE,
        message="waiting: snake has no contour",
        code=ServoReason.NOT_SEEDED,
    )
    assert zero_banner(waiting, passing) == "servo side at zero: waiting: snake has no contour"
    healthy = ServoState(stage=ServoStage.ACQUIRE, message="snake healthy 3 frame(s)")
    assert zero_banner(healthy, None) == ""
    state = JointState(
        names=("j1", "j2"), position=np.radians([0.0, 45.0]), velocity=np.radians([10.0, 0.0])
    )
    rows = joints_view(state, np.radians([-90, -90]), np.radians([90, 90]), np.radians([20, 20]))
    assert rows[1]["q_deg"] == 45.0 and rows[1]["q_frac"] == 0.75
    assert rows[0]["qd_frac"] == 0.5


def test_access_token_rules(tmp_path) -> None:
    assert is_loopback("127.0.0.1") and is_loopback("::1") and is_loopback("localhost")
    assert not is_loopback("0.0.0.0") and not is_loopback("192.168.1.4")
    # loopback too: every run makes a fresh token unless a file gives one
    first, second = resolve_token("", "c"), resolve_token("", "c")
    assert len(first) >= 30 and first != second
    (tmp_path / "t").write_text("0123456789abcdefXYZ\nignored\n")
    assert resolve_token(str(tmp_path / "t"), "c") == "0123456789abcdefXYZ"
    assert token_matches("abc", "abc")
    assert not token_matches("abc", None) and not token_matches("abc", "abd")
    assert not token_matches("", None) and not token_matches("", "")  # no token: nobody


def test_a_page_origin_and_a_port_are_checked_by_their_one_rule() -> None:
    from umbra.connectors.access.hosts import MAX_TCP_PORT, origin_problem, port_problem

    for origin in ("http://127.0.0.1:8080", "https://app.foxglove.dev", "http://[::1]:9/"):
        assert origin_problem(origin) == "", origin
    for origin in ("127.0.0.1:8080", "ftp://host", "http://host/page", "http://host:port", ""):
        assert "expected a page origin" in origin_problem(origin), origin
    assert port_problem(0) == port_problem(MAX_TCP_PORT) == ""
    assert port_problem(MAX_TCP_PORT + 1).endswith(f"found {MAX_TCP_PORT + 1}")
    assert port_problem(-1) != ""
