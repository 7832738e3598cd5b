"""The Sketch module in the harness: snapshot, place, plan, VCR commands, refusals."""

from __future__ import annotations

import numpy as np

from umbra.connectors.messages import Image, JointState, Pose, Text
from umbra.connectors.ptu_messages import PtuState
from umbra.connectors.sketch_messages import SketchReply
from umbra.modules.arm.dh import puma560
from umbra.modules.sketch.session import Q_READY, SketchSession
from umbra.modules.sketch.sketch_module import Sketch
from umbra.modules.sketch.stereo import StereoPair
from umbra.runtime.harness import ModuleHarness


def _feed(h: ModuleHarness, session: SketchSession, moving: bool = False) -> None:
    """Models, PTU poses and states, then (a tick later, as a camera renders) the images."""
    for i, side in enumerate("ab"):
        model, _ = session.camera_state(i)
        cam = session.cameras[i]
        pan, tilt = session.ptus[i].angles
        mount = cam.T_base_ptu @ cam.geometry.T_ptu_mount(pan, tilt)
        h.push(f"camera_{side}", model)
        h.push(f"mount_{side}", Pose(matrix=mount, parent="base", child=f"{cam.name}_mount"))
        h.push(f"ptu_state_{side}", PtuState(pan=pan, tilt=tilt, moving=moving))
    h.push("joint_state", JointState(names=puma560().names, position=Q_READY, gripper=1.0))
    h.step(0.01)
    for i, side in enumerate("ab"):
        frame = session.cameras[i].name
        h.push(f"image_{side}", Image(pixels=np.zeros((480, 640, 3), np.uint8), frame=frame))


def _images(h: ModuleHarness) -> None:
    for side in "ab":
        h.push(f"image_{side}", Image(pixels=np.zeros((480, 640, 3), np.uint8), frame=side))


def _say(h: ModuleHarness, text: str):
    h.push("command", Text(text=text))
    h.step(0.05)
    return h.output("status")


def test_a_snapshot_that_cannot_settle_is_refused_after_snapshot_wait():
    session = SketchSession(seed=2)
    with ModuleHarness(Sketch, {"snapshot_wait": 0.4}) as h:
        _feed(h, session, moving=True)
        _feed(h, session)
        h.push("command", Text(text="snapshot"))
        h.run(60, 0.01)  # no new frame arrives
        status = h.output("status")
        assert status.stage == SketchReply.REFUSED and status.message == (
            "snapshot: camera a has no frame since its view or zoom last changed; wait for the "
            "next frame (waited 0.4 s)"
        )


def test_snapshot_place_plan_and_vcr():
    session = SketchSession(seed=2)
    pipe = session.scene.pipe
    session.aim(pipe.center, zoom=0.3)
    with ModuleHarness(Sketch, {}) as h:
        _feed(h, session, moving=True)
        status = _say(h, "snapshot")
        assert status.stage == SketchReply.REFUSED and "PTU a is still slewing" in status.message
        _feed(h, session)
        # the PTUs were seen moving just before these frames: the snapshot waits for them to
        # settle and for a frame taken after that (no reply until then)
        replies = len(h.outputs("status"))
        h.push("command", Text(text="snapshot"))
        h.run(25, 0.01)
        assert len(h.outputs("status")) == replies and not h.outputs("snapshot")
        refused = _say(h, "place point 1,1 | 2,2")
        assert "place: a snapshot is being taken; send it again after that" in refused.message
        _images(h)
        h.step(0.01)
        assert h.output("status").message == "snapshot snap1"
        snap = h.output("snapshot")
        pair = StereoPair.from_snapshot(snap)
        a, b = pair.project("a", pipe.ends), pair.project("b", pipe.ends)
        text = "place line " + " ".join(f"{u},{v}" for u, v in a) + " | "
        text += " ".join(f"{u},{v + 7}" for u, v in b)  # 7 px off: put back on the line
        status = _say(h, text)
        assert status.stage == SketchReply.OK and status.message.startswith("line1 placed")
        prim = h.output("primitive")
        assert np.max(np.linalg.norm(prim.points - pipe.ends, axis=1)) < 0.003
        assert np.max(pair.epipolar_error_px(prim.pixels_a, prim.pixels_b)) < 1e-6
        assert _say(h, "plan grab_pipe line1").message.startswith("path1 (grab_pipe) checked")
        assert h.output("path").ok and h.output("path").macro == "grab_pipe"
        assert _say(h, "vcr play").stage == SketchReply.OK
        vcr = h.output("vcr")
        assert vcr.action == "play" and vcr.path_id == "path1" and vcr.speed == 0.0
        assert h.output("ptu_a").mode == "point"  # cameras slew to watch the macro's goal
        _say(h, "vcr speed 0.4")
        assert h.output("vcr").speed == 0.4
        refused = _say(h, "plan grab_pipe line9")
        assert refused.stage == SketchReply.REFUSED and "no primitive 'line9'" in refused.message
        far = _say(h, "place line 1,1 2,2 | 3,3")
        assert far.stage == SketchReply.REFUSED and "a line has 2 vertices" in far.message
        bad = _say(h, "wiggle")
        assert bad.stage == SketchReply.REFUSED
        assert "expected one of aim, zoom, snapshot" in bad.message


def test_refused_plans_are_shown_not_sent_and_no_plan_while_the_arm_moves():
    from umbra.connectors.path_messages import VcrState

    session = SketchSession(seed=2)
    session.aim(session.scene.pipe.center, zoom=0.1)
    with ModuleHarness(Sketch, {}) as h:
        _feed(h, session)
        _say(h, "snapshot")
        pair = StereoPair.from_snapshot(h.output("snapshot"))
        far = np.array([[1.7, -0.1, 0.3], [1.7, 0.1, 0.3]])  # beyond the arm's reach
        a, b = pair.project("a", far), pair.project("b", far)
        text = "place line " + " ".join(f"{u},{v}" for u, v in a) + " | "
        _say(h, text + " ".join(f"{u},{v}" for u, v in b))
        refused = _say(h, "plan grab_pipe line1")
        assert refused.stage == SketchReply.REFUSED
        assert "plan grab_pipe: refused: reach:" in refused.message
        assert not h.outputs("path")  # nothing for the player
        preview = h.output("plan_preview")
        assert not preview.ok and preview.reason.startswith("reach:")  # shown, with the reason
        assert _say(h, "vcr play").message == "vcr: plan a macro first"
        assert not h.outputs("vcr")
        # a canned motion is planned from the arm's joints: not while the player moves them
        h.push("vcr_state", VcrState(path_id="path7", mode="playing"))
        busy = _say(h, "plan stow")
        assert busy.stage == SketchReply.REFUSED
        assert "the arm is moving (path7 playing)" in busy.message
        h.push("vcr_state", VcrState(path_id="path7", mode="paused"))
        assert _say(h, "plan stow").stage == SketchReply.OK and h.output("path").macro == "stow"
        for text, message in (
            ("vcr fly", "expected vcr ACTION [NUMBER] with ACTION one of play"),
            ("vcr speed 3", "expected a speed within 0.1 .. 1"),
            ("vcr speed nan", "must be finite"),
            ("vcr seek", "expected vcr seek S"),
            ("plan move_around_axis line1 angle_deg=1e308", "must be a number within -180"),
            ("aim 0.6 0 0.3 5", "expected aim X Y Z [ZOOM] with 0 <= ZOOM <= 1"),
        ):
            bad = _say(h, text)
            assert bad.stage == SketchReply.REFUSED and message in bad.message, (text, bad.message)
        assert len(h.outputs("vcr")) == 0 and len(h.outputs("ptu_a")) == 0


def test_a_triad_keeps_its_box_by_make_box():
    session = SketchSession(seed=2)
    pkg = session.scene.package
    session.aim(pkg.center, zoom=0.2)
    sx, sy, sz = pkg.size
    c, s = np.cos(pkg.yaw), np.sin(pkg.yaw)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    corner = pkg.center + R @ [-sx / 2, -sy / 2, 0]
    points = np.stack([corner, corner + R @ [sx, 0, 0], corner + R @ [0, sy, 0]])
    points = np.vstack([points, corner + np.array([0, 0, sz])])
    with ModuleHarness(Sketch, {}) as h:
        _feed(h, session)
        _say(h, "snapshot")
        pair = StereoPair.from_snapshot(h.output("snapshot"))
        a, b = pair.project("a", points), pair.project("b", points)
        text = "place triad " + " ".join(f"{u},{v}" for u, v in a) + " | "
        status = _say(h, text + " ".join(f"{u},{v}" for u, v in b))
        assert status.message.endswith("macros: make_box") and not h.outputs("box")
        assert _say(h, "plan make_box triad1").message.startswith("box triad1 kept")
        box = h.output("box")
        assert (
            np.linalg.norm(box.T_base_box[:3, 3] - (pkg.center + np.array([0, 0, sz / 2]))) < 0.005
        )
        assert np.allclose(box.size, pkg.size, atol=0.005)
        assert not h.outputs("path")  # no motion
