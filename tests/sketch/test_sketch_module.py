"""The Sketch module in the harness: snapshot, place, plan, VCR commands, refusals."""

from __future__ import annotations

import numpy as np

from connectors.messages import Image, JointState, Pose, Text
from connectors.sketch_messages import PtuState
from modules.arm.dh import puma560
from modules.sketch.session import Q_READY, SketchSession
from modules.sketch.sketch_module import Sketch
from modules.sketch.stereo import StereoPair
from runtime.harness import ModuleHarness


def _feed(h: ModuleHarness, session: SketchSession, moving: bool = False) -> None:
    for i, side in enumerate("ab"):
        model, _ = session.camera_state(i)
        cam = session.cameras[i]
        pan, tilt = session.ptus[i].angles
        mount = cam.T_base_ptu @ cam.geometry.T_ptu_mount(pan, tilt)
        h.push(f"image_{side}", Image(pixels=np.zeros((480, 640, 3), np.uint8), frame=model.frame))
        h.push(f"camera_{side}", model)
        h.push(f"mount_{side}", Pose(matrix=mount, parent="base", child=f"{cam.name}_mount"))
        h.push(f"ptu_state_{side}", PtuState(pan=pan, tilt=tilt, moving=moving))
    h.push("joint_state", JointState(names=puma560().names, position=Q_READY, gripper=1.0))


def _say(h: ModuleHarness, text: str):
    h.push("command", Text(text=text))
    h.step(0.05)
    return h.output("status")


def test_snapshot_place_plan_and_vcr():
    session = SketchSession(seed=2)
    pipe = session.scene.pipe
    session.aim(pipe.center, zoom=0.3)
    with ModuleHarness(Sketch, {}) as h:
        _feed(h, session, moving=True)
        status = _say(h, "snapshot")
        assert status.stage == "refused" and "PTU a is still slewing" in status.message
        _feed(h, session)
        assert _say(h, "snapshot").message == "snapshot snap1"
        snap = h.output("snapshot")
        pair = StereoPair.from_snapshot(snap)
        a, b = pair.project("a", pipe.ends), pair.project("b", pipe.ends)
        text = "place line " + " ".join(f"{u},{v}" for u, v in a) + " | "
        text += " ".join(f"{u},{v + 7}" for u, v in b)  # 7 px off: put back on the line
        status = _say(h, text)
        assert status.stage == "ok" and status.message.startswith("line1 placed")
        prim = h.output("primitive")
        assert np.max(np.linalg.norm(prim.points - pipe.ends, axis=1)) < 0.003
        assert np.max(pair.epipolar_error_px(prim.pixels_a, prim.pixels_b)) < 1e-6
        assert _say(h, "plan grab_pipe line1").message.startswith("path1 (grab_pipe) checked")
        assert h.output("path").ok and h.output("path").macro == "grab_pipe"
        assert _say(h, "vcr play").stage == "ok"
        vcr = h.output("vcr")
        assert vcr.action == "play" and vcr.path_id == "path1" and vcr.speed == 0.0
        assert h.output("ptu_a").mode == "point"  # cameras slew to watch the macro's goal
        _say(h, "vcr speed 0.4")
        assert h.output("vcr").speed == 0.4
        refused = _say(h, "plan grab_pipe line9")
        assert refused.stage == "refused" and "no primitive 'line9'" in refused.message
        far = _say(h, "place line 1,1 2,2 | 3,3")
        assert far.stage == "refused" and "a line has 2 vertices" in far.message
        bad = _say(h, "wiggle")
        assert bad.stage == "refused" and "expected one of aim, zoom, snapshot" in bad.message
