"""Every solid of the Active Sketch scene sits at a proper rigid pose (a rotation, determinant
+1, never a mirror image), and the door keeps its geometry: front face, handle in front of it,
opening towards the arm by the right-hand rule about its hinge line taken top to bottom."""

from __future__ import annotations

import numpy as np
import pytest

from umbra.modules.world.scene_objects import SketchScene, targets_from_objects


def _scenes() -> list[SketchScene]:
    rng = np.random.default_rng(7)
    scenes = [SketchScene.nominal()] + [SketchScene.random(rng) for _ in range(10)]
    return [s.with_door_angle(a) for s in scenes for a in (0.0, 0.4, np.radians(85.0))]


def _rotate_about(point: np.ndarray, a: np.ndarray, b: np.ndarray, angle: float) -> np.ndarray:
    """``point`` turned by ``angle`` (rad) about the line from ``a`` to ``b`` (right-hand rule
    about the direction a -> b; Rodrigues)."""
    k = (b - a) / np.linalg.norm(b - a)
    p = point - a
    turned = p * np.cos(angle) + np.cross(k, p) * np.sin(angle) + k * (k @ p) * (1 - np.cos(angle))
    return a + turned


@pytest.mark.parametrize("scene", _scenes(), ids=lambda s: f"door{np.degrees(s.door.angle):.0f}")
def test_every_solid_has_a_proper_rotation(scene: SketchScene) -> None:
    for name, _, T, _, _ in scene.solids():
        R = T[:3, :3]
        np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12, err_msg=name)
        assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-12), name
        np.testing.assert_array_equal(T[3], [0.0, 0.0, 0.0, 1.0])
    assert np.linalg.det(scene.door.R_base_panel) == pytest.approx(1.0, abs=1e-12)


def test_the_closed_door_panel_handle_and_hinge_are_where_the_docstring_says() -> None:
    door = SketchScene.nominal().door
    solids = {s[0]: s for s in SketchScene.nominal().solids()}
    _, _, T, size, _ = solids["door"]
    half = T[:3, :3] @ np.diag(size / 2)  # the box's half-axes in the base frame
    corners = np.array(
        [T[:3, 3] + half @ [sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]
    )
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    # front face in the plane x = hinge x, the back 2 cm behind it; from the hinge along -y
    np.testing.assert_allclose(lo, door.hinge - np.array([0.0, door.width, 0.0]), atol=1e-12)
    np.testing.assert_allclose(
        hi, door.hinge + np.array([door.thickness, 0.0, door.height]), atol=1e-12
    )
    # the handle stands 5 cm in front (towards the arm), 18 cm along, 22 cm up
    np.testing.assert_allclose(
        door.handle_center, door.hinge + np.array([-0.05, -0.18, 0.22]), atol=1e-12
    )
    np.testing.assert_allclose(door.handle_axis, [0.0, -1.0, 0.0], atol=1e-12)
    hinge = targets_from_objects(SketchScene.nominal().message())["hinge"]
    np.testing.assert_allclose(hinge, [door.hinge_top, door.hinge], atol=1e-12)


def test_the_door_opens_by_the_right_hand_rule_about_its_hinge_top_to_bottom() -> None:
    scene = SketchScene.nominal()
    top, bottom = targets_from_objects(scene.message())["hinge"]
    closed = scene.door
    for angle in (0.2, np.radians(80.0)):
        opened = scene.with_door_angle(angle).door
        np.testing.assert_allclose(
            opened.handle_center,
            _rotate_about(closed.handle_center, top, bottom, angle),
            atol=1e-12,
        )
        np.testing.assert_allclose(
            opened.R_base_panel[:, 0],
            _rotate_about(closed.handle_axis, np.zeros(3), bottom - top, angle),
            atol=1e-12,
        )
        assert opened.handle_center[0] < closed.handle_center[0] - 0.01  # towards the arm
