"""Active Sketch on the simulated cell through the Python API: snapshot, clicks, plan, VCR."""

from __future__ import annotations

import numpy as np
import pytest

from umbra.modules.sketch.session import SessionError, SketchSession
from umbra.modules.sketch.stereo import StereoPair


def _line_on(session: SketchSession, ends, rng, sigma=0.5):
    a, b = session.true_pixels(ends)
    a = a + rng.normal(0, sigma, a.shape)
    # the right-hand clicks are 9 px off the epipolar line (the constraint pulls them back on)
    # and off by the pixel noise along it
    pair = StereoPair.from_snapshot(session.snapshots[list(session.snapshots)[-1]])
    normal = pair.epipolar_line_b(a)[:, :2]
    along = normal @ np.array([[0.0, 1.0], [-1.0, 0.0]])
    b = b + 9.0 * normal + rng.normal(0, sigma, (2, 1)) * along
    return session.place("line", a, b)


def test_grab_pipe_with_pause_back_up_and_resume_grasps_the_pipe():
    session = SketchSession(seed=4)
    rng = np.random.default_rng(4)
    pipe = session.scene.pipe
    session.aim(pipe.center, zoom=0.3)
    snap = session.snapshot()
    assert snap.zoom_a == pytest.approx(0.3) and snap.image_a.shape == (480, 640, 3)
    line = _line_on(session, pipe.ends, rng)
    assert np.max(np.linalg.norm(line.points - pipe.ends, axis=1)) < 0.004
    path = session.plan("grab_pipe", line.primitive_id)
    assert path.ok, path.reason
    script = [
        (0.0, "play", {}),
        (2.5, "pause", {}),
        (3.0, "back", {}),
        (4.0, "pause", {}),
        (4.5, "play", {"speed": 0.4}),
        (6.0, "speed", {"speed": 1.0}),
    ]
    log = session.play(path.path_id, script, timeout=30.0)
    arr = log.arrays()
    assert arr["mode"][-1] == "done"
    verdicts = session.judge.verdicts
    assert verdicts.success("grab_pipe"), verdicts.events
    assert verdicts.grasp_distance_m < 0.005 and np.degrees(verdicts.grasp_angle_rad) < 3.0
    # pause: standstill (|s_dot| < 1e-9) within 0.3 s of the command, and the guard never tripped
    t, s_dot = arr["t"], arr["s_dot"]
    paused = np.flatnonzero((t > 2.5) & (np.abs(s_dot) < 1e-9))[0]
    assert t[paused] - 2.5 <= 0.3
    assert not any(arr["guard"])
    # backing up retraces the forward tool path within 1 mm
    forward = arr["tool"][(t < 3.0)]
    backing = arr["tool"][(t > 3.0) & (t < 4.0)]
    gaps = np.linalg.norm(backing[:, None, :] - forward[None, :, :], axis=2).min(axis=1)
    assert gaps.max() < 0.001
    # no velocity jump at any command: joint rates change by at most accel * dt per tick
    jumps = np.abs(np.diff(arr["qd"], axis=0)).max()
    assert jumps < 8.0 * session.dt


def test_door_opens_by_move_around_axis_from_the_handle_grip():
    session = SketchSession(seed=7)
    rng = np.random.default_rng(7)
    door = session.scene.door
    session.aim(door.handle_center, zoom=0.2)
    session.snapshot(render=False)
    handle = _line_on(
        session,
        np.stack(
            [
                door.handle_center - 0.05 * door.handle_axis,
                door.handle_center + 0.05 * door.handle_axis,
            ]
        ),
        rng,
    )
    grab = session.plan("grab_pipe", handle.primitive_id)
    session.play(grab.path_id)
    assert session.judge.verdicts.handle_held
    session.aim(door.hinge + np.array([0.0, 0.0, 0.2]), zoom=0.1)
    session.snapshot(render=False)
    hinge = _line_on(session, np.stack([door.hinge_top, door.hinge]), rng)
    sweep = session.plan("move_around_axis", hinge.primitive_id, {"angle_deg": 85})
    assert sweep.ok, sweep.reason
    session.play(sweep.path_id)
    v = session.judge.verdicts
    assert v.success("move_around_axis") and np.degrees(v.door_max_rad) > 80.0
    assert np.degrees(session.scene.door.angle) > 80.0


def test_refused_or_stale_paths_are_not_played():
    session = SketchSession(seed=1)
    session.snapshot(render=False)
    a, b = session.true_pixels(np.array([[1.7, -0.1, 0.3], [1.7, 0.1, 0.3]]))
    far = session.place("line", a, b)
    path = session.plan("grab_pipe", far.primitive_id)
    assert not path.ok
    with pytest.raises(SessionError, match="was refused: reach"):
        session.play(path.path_id)
    ready = session.plan("stow")
    session.play(ready.path_id)
    with pytest.raises(SessionError, match="the arm has moved since path2 was planned"):
        session.play(ready.path_id)
