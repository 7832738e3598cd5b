"""Snapshots and sketched geometry in the 3-D view: a snapshot's frustum with its image, boxes
and primitives (a mixin of :class:`~umbra.modules.view3d.viewer.ViewerPage`)."""

from __future__ import annotations

from typing import Any

import numpy as np

from umbra.modules.view3d.geometry import Frustum, wxyz_from_matrix
from umbra.modules.view3d.scene_file import SceneBox, ScenePrimitive, SceneSnapshot
from umbra.modules.view3d.viewer_video import SNAPSHOT_SCALE, node_name, video_rgba


class ViewerSketch:
    """Snapshots, boxes and primitives on the page."""

    server: Any
    snapshots: dict[str, tuple[SceneSnapshot, Frustum]]
    snapshot_dropdown: Any
    video_width: int
    add_box: Any

    def add_snapshot(self, snapshot: SceneSnapshot, frustum: Frustum) -> None:
        self.snapshots[snapshot.id] = (snapshot, frustum)
        self.server.scene.add_camera_frustum(
            f"/snapshots/{node_name(snapshot.id)}",
            fov=frustum.fov_y,
            aspect=frustum.aspect,
            scale=SNAPSHOT_SCALE,
            thickness=2.0,
            thickness_units="screen",
            color=(150, 60, 200),
            image=video_rgba(snapshot.image, 1.0, max(self.video_width, 640)),
            format="jpeg",
            jpeg_quality=90,
            wxyz=wxyz_from_matrix(frustum.T_world_camera[:3, :3]),
            position=tuple(frustum.T_world_camera[:3, 3]),
        )
        self.snapshot_dropdown.options = tuple(self.snapshots)

    def add_scene_box(self, box: SceneBox) -> None:
        self.add_box(
            f"/sketch/boxes/{node_name(box.id)}", box.T_world_box, box.size, (200, 150, 60)
        )

    def add_primitive(self, primitive: ScenePrimitive) -> None:
        name = f"/sketch/primitives/{node_name(primitive.id)}"
        if len(primitive.edges):
            segments = primitive.points[primitive.edges].astype(np.float32)
            self.server.scene.add_line_segments(
                name + "/edges",
                points=segments,
                colors=(220, 40, 160),
                thickness=4.0,
                thickness_units="screen",
            )
        if len(primitive.points):
            self.server.scene.add_point_cloud(
                name + "/vertices",
                points=primitive.points.astype(np.float32),
                colors=(220, 40, 160),
                point_size=0.02,
                point_shape="circle",
            )
        corners = primitive.plane_corners()
        if corners is not None:
            self.server.scene.add_mesh_simple(
                name + "/plane",
                vertices=corners.astype(np.float32),
                faces=np.array([[0, 1, 2], [0, 2, 3]], dtype=np.uint32),
                color=(220, 40, 160),
                opacity=0.35,
                side="double",
            )
