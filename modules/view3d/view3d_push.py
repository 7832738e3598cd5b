"""View3D's sender: a thread of its own that sends the newest samples to the page at most
``max_fps`` times a second and no faster than the browsers apply them
(:mod:`~umbra.modules.view3d.viewer_pace`; nothing while no browser is connected), each part on
its own; and the scene file (a part that :class:`~umbra.modules.view3d.view3d.View3D` owns)."""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from umbra.connectors import UserError
from umbra.connectors.messages import CameraModel, Image, JointState, Pose, Status
from umbra.connectors.scene_messages import SceneObjects
from umbra.connectors.states import Outcome, Verdict
from umbra.modules.view3d.geometry import (
    Frustum,
    arm_joint_points,
    arm_link_segments,
    frustum_from_model,
)
from umbra.modules.view3d.scene_file import (
    Scene,
    SceneBox,
    ScenePrimitive,
    SceneSnapshot,
    save_scene,
)
from umbra.modules.view3d.viewer_video import FRUSTUM_SCALES

if TYPE_CHECKING:
    from umbra.modules.view3d.view3d import View3D

CAMERAS = ("wrist", "left", "right")

#: what the scene keeps: a stereo snapshot, a box placed by a triad, a sketched primitive
SceneItem = SceneSnapshot | SceneBox | ScenePrimitive


class ViewPush:
    """The sender side of a :class:`~umbra.modules.view3d.view3d.View3D`: reads the view's
    parameters, page, log and static frames; keeps the newest samples and the items not yet
    shown (both under ``lock``, which the view's ``step`` shares), the scene and its file, what
    the page shows and the counts of updates, saves and failed parts."""

    def __init__(self, view: View3D, lock: threading.Lock, scene: Scene, scene_path: Path) -> None:
        self._v = view
        self._lock = lock
        self.latest: dict[str, object] = {}  #: the newest sample of each input (under lock)
        self.new_items: list[SceneItem] = []  #: items the page does not show yet (under lock)
        self.scene = scene
        self.scene_path = scene_path
        self._scene_dirty = False
        self.saves = 0
        self.updates = 0  #: updates sent to a browser
        self.held = 0  #: turns without an update: a browser had not applied the last one
        self._skipped_idle = 0
        self._shown: dict[str, object] = {}  # the samples on the page now, by input
        self.failed = 0  # parts of updates that failed (malformed samples)
        self._warned: set[str] = set()
        self._stopping = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        """Start the sender thread."""
        self._thread = threading.Thread(
            target=self._pusher, name=f"{self._v.name}-view3d", daemon=True
        )
        self._thread.start()

    def add_item(self, item: SceneItem) -> None:
        """Keep ``item`` for the page's next update (any thread)."""
        with self._lock:
            self.new_items.append(item)

    def stop(self) -> None:
        """Stop the sender; keep the items that arrived after its last turn; save the scene."""
        if self._thread is not None:
            self._stopping.set()
            self._thread.join(timeout=5.0)
        if self.new_items:  # arrived after the sender's last turn: keep them too
            for item in self.new_items:
                if isinstance(item, SceneSnapshot):
                    self.scene.snapshots[item.id] = item
                elif isinstance(item, SceneBox):
                    self.scene.boxes[item.id] = item
                else:
                    self.scene.primitives[item.id] = item
            self._scene_dirty = True
        if self._scene_dirty:
            self._save()

    def _pusher(self) -> None:
        period = 1.0 / self._v.params.max_fps
        while not self._stopping.is_set():
            started = time.perf_counter()
            with self._lock:
                latest = dict(self.latest)
                items, self.new_items = self.new_items, []
            try:
                self._add_items(items)
                if self._v.page.clients() == 0:
                    self._skipped_idle += 1
                elif self._v.page.pace.ready():
                    self.send(latest)
                    self._v.page.pace.sent()
                    self.updates += 1
                else:  # a browser is still applying the last update: the newest goes next
                    self.held += 1
                if self._scene_dirty:
                    self._save()
            except Exception as error:  # a bad sample must not kill the page
                self._v.log.warning("3-D view update failed: %s", error)
            self._stopping.wait(max(0.0, period - (time.perf_counter() - started)))

    def _add_items(self, items: list[SceneItem]) -> None:
        for item in items:
            if isinstance(item, SceneSnapshot):
                self.scene.snapshots[item.id] = item
                self._v.page.add_snapshot(item, snapshot_frustum(item))
            elif isinstance(item, SceneBox):
                self.scene.boxes[item.id] = item
                self._v.page.add_scene_box(item)
            elif isinstance(item, ScenePrimitive):
                self.scene.primitives[item.id] = item
                self._v.page.add_primitive(item)
            self._scene_dirty = True

    def save_now(self) -> str:
        """Save the scene now; its file's path."""
        self._save()
        return str(self.scene_path)

    def _save(self) -> None:
        self._scene_dirty = False
        try:
            save_scene(self.scene, self.scene_path)
            self.saves += 1
        except (OSError, UserError) as error:
            self._v.log.warning("cannot save the scene to %s: %s", self.scene_path, error)

    def send(self, latest: dict[str, object]) -> None:
        """Send what changed to the page. Each part (arm, workcell, solids, each camera) is
        sent on its own: a malformed sample spoils its own part, never the others."""
        q = latest.get("joint_state")
        T_world_flange = None
        with self._part("arm"):
            if isinstance(q, JointState):
                table = self._v.params.table
                T_world_flange = self._v._T_world_base @ table.fk(q.position)
            if isinstance(q, JointState) and self._shown.get("joint_state") is not q:
                self._shown["joint_state"] = q
                points = arm_joint_points(
                    table, q.position, self._v._T_world_base, self._v._T_flange_tool
                )
                T_tool = (
                    T_world_flange @ self._v._T_flange_tool
                    if self._v._T_flange_tool is not None
                    else None
                )
                self._v.page.set_arm(arm_link_segments(points), points[: table.n + 1], T_tool)
                if T_tool is not None:
                    self._v.page.label("tool", self._v.params.tool_frame, T_tool)
        stage = latest.get("stage")
        if isinstance(stage, Status) and self._shown.get("stage") is not stage:
            self._shown["stage"] = stage
            with self._part("stage"):
                self._v.page.set_stage(stage_line(stage))
        verdict = latest.get("verdict")
        if isinstance(verdict, Verdict) and self._shown.get("verdict") is not verdict:
            self._shown["verdict"] = verdict
            with self._part("verdict"):
                self._v.page.set_verdict(verdict_words(verdict, ended=False))
        patch = latest.get("patch_pose")
        if isinstance(patch, Pose) and self._shown.get("patch_pose") is not patch:
            self._shown["patch_pose"] = patch
            with self._part("workcell"):
                self.draw_static(patch)
        objects = latest.get("objects")
        if isinstance(objects, SceneObjects) and self._shown.get("objects") is not objects:
            self._shown["objects"] = objects
            with self._part("scene objects"):
                T = self._v._to_world(objects.frame)
                poses = np.einsum(
                    "ij,njk->nik", T, np.asarray(objects.poses, dtype=float).reshape(-1, 4, 4)
                )
                refused = self._v.page.set_objects(
                    objects.names,
                    objects.kinds,
                    poses,
                    np.asarray(objects.sizes, dtype=float).reshape(-1, 3),
                    np.asarray(objects.colors).reshape(-1, 3),
                )
                if refused:
                    self._warn_once(
                        f"solids {refused}",
                        "3-D view: solids %s not drawn: their pose is not a rotation (or a "
                        "reflection) with a translation, or their size is not positive",
                        refused,
                    )
        for camera in CAMERAS:
            with self._part(f"camera {camera}"):
                frustum = self._camera_frustum(camera, latest, T_world_flange)
                if frustum is None:
                    continue
                image = latest.get(f"{camera}_image")
                pixels = None
                if isinstance(image, Image) and self._shown.get(f"{camera}_image") is not image:
                    self._shown[f"{camera}_image"] = image
                    pixels = np.asarray(image.pixels)
                self._v.page.set_camera(camera, frustum, pixels)
                self._v.page.label(f"camera {camera}", camera, label_under(frustum, camera))

    @contextlib.contextmanager
    def _part(self, what: str) -> Iterator[None]:
        """Run one part of an update; a failure is logged (once per part and message) and
        counted, and the update goes on with the next part."""
        try:
            yield
        except (ValueError, TypeError, IndexError, UserError, np.linalg.LinAlgError) as error:
            self.failed += 1
            self._warn_once(f"{what}: {error}", "3-D view: %s not updated: %s", what, error)

    def _warn_once(self, key: str, message: str, *args: object) -> None:
        if key not in self._warned:
            self._warned.add(key)
            self._v.log.warning(message, *args)

    def _camera_frustum(
        self, camera: str, latest: dict[str, object], T_world_flange: np.ndarray | None
    ) -> Frustum | None:
        p = self._v.params
        model = latest.get(f"{camera}_model")
        pose = latest.get(f"{camera}_pose")
        if not isinstance(model, CameraModel):
            # without a model only the wrist camera is drawn (from wrist_intrinsics), and only
            # once it has sent video or a pose: a graph without a wrist camera shows none
            if camera != "wrist" or not (
                isinstance(latest.get("wrist_image"), Image) or isinstance(pose, Pose)
            ):
                return None
            fx, fy, u0, v0, width, height = p.wrist_intrinsics
            model = CameraModel(
                fx=fx,
                fy=fy,
                u0=u0,
                v0=v0,
                width=int(width),
                height=int(height),
                mount=p.tool_frame,
                frame=p.wrist_frame,
                T_mount_camera=self._v._T_tool_wrist
                if self._v._T_tool_wrist is not None
                else np.eye(4),
            )
        if isinstance(pose, Pose):
            T_world_parent = self._v._lookup(p.world_frame, pose.parent, None)
            if T_world_parent is None:
                return None
            T = T_world_parent @ np.asarray(pose.matrix, dtype=float)
            if pose.child == model.frame:  # the camera's own pose
                return frustum_from_model(model, T @ np.linalg.inv(model.T_mount_camera))
            return frustum_from_model(model, T)
        if (
            camera == "wrist"
            and model.mount == p.tool_frame
            and T_world_flange is not None
            and self._v._T_flange_tool is not None
        ):
            return frustum_from_model(model, T_world_flange @ self._v._T_flange_tool)
        T_world_mount = self._v._lookup(p.world_frame, model.mount, None)
        return None if T_world_mount is None else frustum_from_model(model, T_world_mount)

    def draw_static(self, patch: Pose | None) -> None:
        """Draw the table, and with the patch's pose the tray and the tool on it."""
        p = self._v.params
        if self._v._T_world_table is None:
            return
        T_table = self._v._T_world_table
        top = np.eye(4)
        top[2, 3] = -p.table_size_m[2] / 2.0
        self._v.page.add_box(
            "/workcell/table", T_table @ top, np.array(p.table_size_m), (190, 170, 140)
        )
        self._v.page.label("table", p.table_frame, T_table)
        self._v.page.label("base", "base", self._v._T_world_base)
        if patch is None:
            return
        T_world_patch = self._v._lookup(p.world_frame, patch.parent, np.eye(4)) @ np.asarray(
            patch.matrix, dtype=float
        )
        height = float(T_world_patch[2, 3] - T_table[2, 3])
        on_table = T_world_patch.copy()
        on_table[:3, 3] -= T_table[:3, 2] * height
        tray = on_table.copy()
        tray[:3, 3] += T_table[:3, 2] * p.tray_size_m[2] / 2.0
        self._v.page.add_box("/workcell/tray", tray, np.array(p.tray_size_m), (120, 120, 130))
        body = on_table.copy()
        body[:3, 3] += T_table[:3, 2] * (height / 2.0)
        size = np.array([p.tool_size_m[0], p.tool_size_m[1], max(height, 1e-3)])
        self._v.page.add_box("/workcell/tool", body, size, (70, 70, 80))


def snapshot_frustum(snapshot: SceneSnapshot) -> Frustum:
    """The frustum of a scene snapshot (its own pose and intrinsics)."""
    K = snapshot.K
    model = CameraModel(
        fx=float(K[0, 0]),
        fy=float(K[1, 1]),
        skew=float(K[0, 1]),
        u0=float(K[0, 2]),
        v0=float(K[1, 2]),
        width=snapshot.width,
        height=snapshot.height,
    )
    return frustum_from_model(model, snapshot.T_world_camera)


def stage_line(status: Status) -> str:
    """The page's state line of a task status: the stage, its message, and why it asks for
    help when it does."""
    line = status.stage
    if status.message:
        line += f": {status.message}"
    if status.assist and status.reason:
        line += f" (asks the operator: {status.reason})"
    return line


def verdict_words(verdict: Verdict | None, ended: bool = True) -> str:
    """The verdict as the page says it: the judge's words once it judged; "" before that while
    the run lives, and at its end what is known (``ended``)."""
    if verdict is not None and verdict.outcome != Outcome.PENDING:
        return verdict.message or verdict.outcome.value
    return "no verdict (the run was stopped before it was judged)" if ended else ""


def label_under(frustum: Frustum, camera: str) -> np.ndarray:
    """Where a camera's name goes: a quarter of the image's height under its drawn image, so
    that it never covers the video (T_world_label, m)."""
    w, h = frustum.width, frustum.height
    depth = frustum.image_depth(FRUSTUM_SCALES.get(camera, 0.15))
    at = frustum.points_from_pixels(np.array([[w / 2, 1.25 * h]]), depth)[0]
    T = np.eye(4)
    T[:3, 3] = at
    return T
