"""Active Sketch in the station's 3-D panel, without a browser: the snapshots' frusta, the
primitives and the path in the arm's base frame, the arm's place on the path, and the console
passing them to the page."""

from __future__ import annotations

import math

import numpy as np

from tests.operator.helpers import image
from umbra.connectors.messages import Poses
from umbra.connectors.path_messages import ToolPath, VcrState
from umbra.connectors.sketch_messages import SketchPrimitive, StereoSnapshot
from umbra.modules.operator.console import OperatorConsole
from umbra.modules.operator.sketch_scene import MAX_PATH_POINTS, MAX_SNAPSHOTS, SketchItems
from umbra.runtime.harness import ModuleHarness

T_BASE_TABLE = np.eye(4)
T_BASE_TABLE[:3, 3] = [0.1, -0.2, 0.25]


def _lookup(frame: str) -> np.ndarray | None:
    return {"base": np.eye(4), "table": T_BASE_TABLE}.get(frame)


def _translation(xyz: list[float], down: bool = False) -> np.ndarray:
    """A pose at ``xyz`` [m]; ``down``: its z axis points down (a camera looking at the table)."""
    T = np.diag([1.0, -1.0, -1.0, 1.0]) if down else np.eye(4)
    T[:3, 3] = xyz
    return T


def snapshot(snapshot_id: str = "s1", frame: str = "base") -> StereoSnapshot:
    K = np.array([[400.0, 0, 320], [0, 400.0, 240], [0, 0, 1]])
    pixels = np.zeros((480, 640, 3), np.uint8)
    return StereoSnapshot(
        snapshot_id=snapshot_id,
        image_a=pixels,
        image_b=pixels,
        K_a=K,
        K_b=K,
        T_base_camera_a=_translation([0.2, 0.15, 0.9], down=True),
        T_base_camera_b=_translation([0.2, -0.15, 0.9], down=True),
        camera_a_name="cam_left",
        camera_b_name="cam_right",
        frame=frame,
    )


def path(n: int = 11) -> ToolPath:
    s = np.linspace(0.0, 1.0, n)
    poses = np.stack([_translation([0.4 + 0.2 * si, 0.0, 0.1]) for si in s])
    return ToolPath(
        path_id="p1",
        macro="grab pipe",
        names=("j1",),
        s=s,
        joints=np.zeros((n, 1)),
        T_base_tool=poses,
        gripper=np.ones(n),
        frame="table",
    )


def test_items_are_placed_in_the_base_frame_and_the_arm_on_the_path() -> None:
    items = SketchItems()
    assert not items
    items.add_snapshot(snapshot())
    items.add_primitive(
        SketchPrimitive(
            primitive_id="l1",
            kind="line",
            points=np.array([[0.0, 0.0, 0.0], [0.3, 0.0, 0.0]]),
            edges=np.array([[0, 1]]),
            frame="table",
        )
    )
    items.set_path(path())
    vcr = VcrState(path_id="p1", mode="playing", s=0.25, progress=0.25)
    view = items.view(_lookup, vcr)
    cams = view["snapshots"][0]["cameras"]
    assert [c["name"] for c in cams] == ["cam_left", "cam_right"]
    assert cams[0]["T"][3] == 0.2 and cams[0]["T"][7] == 0.15 and cams[0]["T"][11] == 0.9
    assert math.isclose(cams[0]["tan_half_fov_x"], 320 / 400) and math.isclose(
        cams[0]["aspect"], 4 / 3, rel_tol=1e-4
    )
    # the table is 0.25 m up and moved in x, y: the line's ends follow
    assert view["primitives"][0]["points"] == [[0.1, -0.2, 0.25], [0.4, -0.2, 0.25]]
    assert view["primitives"][0]["edges"] == [[0, 1]]
    p = view["path"]
    assert p["points"][0] == [0.5, -0.2, 0.35] and p["points"][-1] == [0.7, -0.2, 0.35]
    assert p["at"] == [0.55, -0.2, 0.35]  # s = 0.25 of the way: interpolated
    assert (p["progress"], p["mode"], p["macro"]) == (0.25, "playing", "grab pipe")
    # another path in the player: the arm is not on this one
    other = items.view(_lookup, VcrState(path_id="p0", mode="playing", s=0.5))
    assert other["path"]["at"] is None and other["path"]["progress"] is None


def test_untied_frames_are_counted_not_drawn_and_the_lists_are_bounded() -> None:
    items = SketchItems()
    for k in range(MAX_SNAPSHOTS + 3):
        items.add_snapshot(snapshot(f"s{k}"))
    items.add_snapshot(snapshot("s2"))  # taken again: the newer replaces it, kept last
    items.add_snapshot(snapshot("far", frame="mars"))
    view = items.view(_lookup, None)
    assert len(items.snapshots) == MAX_SNAPSHOTS
    assert [s["id"] for s in view["snapshots"]] == ["s5", "s6", "s2"]
    assert view["untied"] == 1
    items.set_path(path(5 * MAX_PATH_POINTS))
    assert len(items.view(_lookup, None)["path"]["points"]) == MAX_PATH_POINTS


def test_the_console_hands_the_items_to_its_page() -> None:
    frames = {"base->table": T_BASE_TABLE}
    with ModuleHarness(OperatorConsole, {}, frames=frames) as h:
        h.push("image", image())
        h.push(
            "link_poses",
            Poses(matrices=np.stack([np.eye(4)]), children=["link1"], frame="base"),
        )
        h.step(dt=0.01)
        assert "sketch" not in h.module.view.scene(h.now)  # nothing sketched yet
        h.push("snapshot", snapshot())
        h.push("path", path())
        h.push("vcr_state", VcrState(path_id="p1", mode="paused", s=0.5, progress=0.5))
        h.step(dt=0.01)
        scene = h.module.view.scene(h.now)
        assert scene["sketch"]["snapshots"][0]["id"] == "s1"
        assert scene["sketch"]["path"]["at"] == [0.6, -0.2, 0.35]
        assert scene["sketch"]["path"]["mode"] == "paused"
