"""Active Sketch's messages as items of the 3-D view's scene (in the view's world frame)."""

from __future__ import annotations

import numpy as np

from umbra.connectors.sketch_messages import SketchBox, SketchPrimitive, StereoSnapshot
from umbra.modules.view3d.scene_file import PRIMITIVE_KINDS, SceneBox, ScenePrimitive, SceneSnapshot


def snapshot_items(snapshot: StereoSnapshot, T_world_frame: np.ndarray) -> list[SceneSnapshot]:
    """The two pictures of a stereo snapshot, ids ``<snapshot_id>/a`` and ``<snapshot_id>/b``,
    posed in the view's world (``T_world_frame`` takes the message's frame to the world)."""
    items = []
    for side in ("a", "b"):
        image = np.array(getattr(snapshot, f"image_{side}"), dtype=np.uint8)  # a copy we keep
        if image.ndim != 3 or image.shape[2] != 3:
            raise ValueError(f"snapshot {snapshot.snapshot_id!r} image {side} is not H x W x 3")
        T = T_world_frame @ np.asarray(getattr(snapshot, f"T_base_camera_{side}"), dtype=float)
        items.append(
            SceneSnapshot(
                id=f"{snapshot.snapshot_id}/{side}",
                camera=getattr(snapshot, f"camera_{side}_name"),
                T_world_camera=T,
                K=np.array(getattr(snapshot, f"K_{side}"), dtype=float),
                image=image,
            )
        )
    return items


def primitive_item(primitive: SketchPrimitive, T_world_frame: np.ndarray) -> ScenePrimitive:
    """A sketched primitive's vertices and edges in the world."""
    if primitive.kind not in PRIMITIVE_KINDS:
        raise ValueError(f"primitive kind must be one of {PRIMITIVE_KINDS}, got {primitive.kind!r}")
    points = np.asarray(primitive.points, dtype=float).reshape(-1, 3)
    points = points @ T_world_frame[:3, :3].T + T_world_frame[:3, 3]
    edges = np.asarray(primitive.edges, dtype=np.int64).reshape(-1, 2)
    if len(edges) == 0 and len(points) > 1:
        if primitive.kind == "triad":
            edges = np.array([[0, k] for k in range(1, len(points))], dtype=np.int64)
        else:
            edges = np.array([[k, k + 1] for k in range(len(points) - 1)], dtype=np.int64)
    return ScenePrimitive(primitive.primitive_id, primitive.kind, points, edges)


def box_item(box: SketchBox, T_world_frame: np.ndarray) -> SceneBox:
    """A triad's box in the world."""
    size = np.asarray(box.size, dtype=float).reshape(3)
    if not np.all(np.isfinite(size)) or np.any(size <= 0):
        raise ValueError(f"box {box.box_id!r} needs 3 positive edge lengths, got {size}")
    return SceneBox(box.box_id, T_world_frame @ np.asarray(box.T_base_box, dtype=float), size)
