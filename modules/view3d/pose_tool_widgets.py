"""The pose tool's controls on the 3-D view's page (viser widgets and scene clicks)."""

from __future__ import annotations

import threading
from collections.abc import Callable
from pathlib import Path

import numpy as np
import viser

from umbra.modules.calib.errors import CalibrationError
from umbra.modules.view3d.pose_tool_panel import PoseTool
from umbra.modules.view3d.viewer import ViewerPage
from umbra.modules.view3d.viewer_video import SNAPSHOT_SCALE


class PoseToolWidgets:
    """A "Pose tool" folder: click mode (image point, then model point), solve, save, clear;
    markers for the clicks and the reprojected points; ``on_solved(T_parent_child)`` gets each
    saved mount."""

    def __init__(
        self, page: ViewerPage, tool: PoseTool, folder: Path, on_saved: Callable[[np.ndarray], None]
    ) -> None:
        self.page = page
        self.tool = tool
        self.folder = folder
        self.on_saved = on_saved
        self._lock = threading.Lock()
        self.markers: list = []
        gui = page.server.gui
        with gui.add_folder(f"Pose tool ({tool.parent}->{tool.child})"):
            self.mode = gui.add_dropdown("click", options=("off", "image point", "model point"))
            self.solve_button = gui.add_button("Solve mount")
            self.save_button = gui.add_button("Save mount")
            self.clear_button = gui.add_button("Clear points")
            self.note = gui.add_markdown(
                "Take snapshots, then click a point in an image and "
                "the same point on the model (3 pairs or more)."
            )
        self.solve_button.on_click(lambda _e: self.solve())
        self.save_button.on_click(lambda _e: self.save())
        self.clear_button.on_click(lambda _e: self.clear())
        page.server.scene.on_click()(self._clicked)

    def _clicked(self, event: viser.SceneClickEvent) -> None:
        with self._lock:
            self.handle_ray(np.array(event.ray_origin), np.array(event.ray_direction))

    def handle_ray(self, origin: np.ndarray, direction: np.ndarray) -> None:
        """A scene click in the current mode (also the entry point of tests)."""
        mode = self.mode.value
        n = len(self.tool.pairs)
        if mode == "image point":
            viewed = str(self.page.snapshot_dropdown.value)
            pair = self.tool.click_image(origin, direction, self.page.snapshots, prefer=viewed)
            if pair is None:
                self.note.content = "no snapshot image under that click"
                return
            _, frustum = self.page.snapshots[pair.snapshot_id]
            depth = self.tool.image_depth(pair.snapshot_id)
            at = frustum.points_from_pixels(pair.pixel[None], depth)
            self._marker(
                f"/pose_tool/pixel_{len(self.tool.pairs)}",
                points=at,
                colors=(230, 30, 30),
                point_size=0.012,
                point_shape="circle",
            )
            self.note.content = (
                f"pixel {pair.pixel[0]:.1f}, {pair.pixel[1]:.1f} in "
                f"{pair.snapshot_id}: now click the same point on the model"
            )
            self.mode.value = "model point"
        elif mode == "model point":
            point = self.tool.click_model(origin, direction, self.page.meshes.values())
            if point is None:
                self.note.content = "click an image point first, then the model's surface"
                return
            self._marker(
                f"/pose_tool/point_{n}",
                points=point[None],
                colors=(30, 180, 30),
                point_size=0.015,
                point_shape="circle",
            )
            done = len(self.tool.complete_pairs())
            self.note.content = f"{done} pairs ({point.round(4).tolist()} m)"
            self.mode.value = "image point"

    def _marker(self, name: str, **kwargs) -> None:
        self.markers.append(self.page.server.scene.add_point_cloud(name, **kwargs))

    def solve(self) -> None:
        try:
            result = self.tool.solve(self.page.snapshots)
        except (CalibrationError, KeyError) as error:
            self.note.content = f"cannot solve: {error}"
            return
        for snapshot_id, residuals in zip(self.tool.result_ids, result.residuals, strict=True):
            pairs = [p for p in self.tool.complete_pairs() if p.snapshot_id == snapshot_id]
            predicted = np.array([p.pixel for p in pairs]) + residuals
            _, frustum = self.page.snapshots[snapshot_id]
            at = frustum.points_from_pixels(predicted, self.tool.image_depth(snapshot_id))
            self._marker(
                f"/pose_tool/reprojected/{snapshot_id.replace('/', '_')}",
                points=at,
                colors=(30, 60, 230),
                point_size=0.01,
                point_shape="diamond",
            )
        angle, offset = self.tool.change()
        self.note.content = (
            f"mount corrected by {angle:.2f} deg and {1000 * offset:.1f} mm; "
            f"RMS {result.rms_px:.2f} px"
            f"\n\n{self.tool.residual_table()}"
        )

    def save(self) -> None:
        try:
            paths = self.tool.save(self.folder, self.page.snapshots)
        except (CalibrationError, OSError) as error:
            self.note.content = f"cannot save: {error}"
            return
        self.on_saved(self.tool.corrected_mount())
        self.note.content += "\n\nsaved " + ", ".join(str(p) for p in paths)

    def clear(self) -> None:
        self.tool.pairs.clear()
        self.tool.result = None
        for handle in self.markers:
            handle.remove()
        self.markers.clear()
        self.note.content = "points cleared"


def snapshot_image_depth(page: ViewerPage) -> Callable[[str], float]:
    """Depth at which the page draws each snapshot's image."""
    return lambda snapshot_id: page.snapshots[snapshot_id][1].image_depth(SNAPSHOT_SCALE)
