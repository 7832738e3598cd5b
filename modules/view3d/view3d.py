"""View3D: the live 3-D view of the workcell (LDRD report section 4), served beside the console."""

from __future__ import annotations

import threading
from pathlib import Path

import numpy as np

from umbra.connectors import Input, Module, Output, UserError, from_param, param
from umbra.connectors.access.secret import resolve_token
from umbra.connectors.messages import CameraModel, Image, JointState, Pose, Status
from umbra.modules.arm.arm_params import ArmParams
from umbra.modules.sketch.messages import SceneObjects, SketchBox, SketchPrimitive, StereoSnapshot
from umbra.modules.view3d.geometry import (
    viewer_pose_looking_at,
)
from umbra.modules.view3d.pose_tool_panel import PoseTool
from umbra.modules.view3d.pose_tool_widgets import PoseToolWidgets, snapshot_image_depth
from umbra.modules.view3d.scene_file import Scene, load_scene
from umbra.modules.view3d.scene_messages import box_item, primitive_item, snapshot_items
from umbra.modules.view3d.view3d_push import CAMERAS, ViewPush
from umbra.modules.view3d.viewer import ViewerPage


class View3DParams(ArmParams):
    """Parameters of the 3-D view (the arm's DH table comes from ArmParams)."""

    host: str = param("127.0.0.1", "address the page listens on (loopback by default)")
    port: int = param(8090, "TCP port of the page; 0: any free port", ge=0, le=65535)
    token_file: str = param(
        "", "file whose first line is the page's access token (else a random one, printed)"
    )
    world_frame: str = param("base", "the view's reference frame (z up)")
    max_fps: float = param(
        10.0, "most scene updates (video frames) sent per second", unit="Hz", gt=0, le=60
    )
    video_width: int = param(
        320, "video is scaled down to this width for the page", unit="px", ge=32, le=1920
    )
    wrist_intrinsics: list[float] = param(
        [800.0, 800.0, 640.0, 360.0, 1280.0, 720.0],
        "wrist camera fx fy u0 v0 width height without a wrist_model input",
        unit="px",
    )
    wrist_frame: str = param("camera", "the wrist camera's frame in the static frames")
    tool_frame: str = param("tool", "frame the arm's tool is (static frame below flange)")
    table_frame: str = param("table", "the table top's frame (z up); '' for no table")
    table_size_m: list[float] = param([1.4, 1.2, 0.04], "table x, y, thickness", unit="m")
    tray_size_m: list[float] = param([0.3, 0.22, 0.01], "tray under the tool x, y, z", unit="m")
    tool_size_m: list[float] = param([0.08, 0.05, 0.03], "tool body x, y, height", unit="m")
    overview_xyz_m: list[float] = param([1.9, -1.6, 1.4], "overview viewer position", unit="m")
    overview_target_m: list[float] = param([0.45, 0.0, 0.3], "overview look-at point", unit="m")
    overview_fov_deg: float = param(
        50.0, "overview vertical field of view", unit="deg", gt=1, lt=170
    )
    animation_s: float = param(1.0, "duration of a viewer move", unit="s", ge=0, le=10)
    scene_file: str = param("scene.json", "scene file in the run folder, saved on every change")
    load_scene: str = param("", "scene file to load at start (a previous run's)")
    pose_tool_mount: str = param(
        "tool->camera", "the static frame parent->child the pose tool corrects (a camera mount)"
    )


class View3D(ViewPush, Module):
    """The live 3-D view: the arm from its DH table moving with the joint state; the table,
    tray and tool, the frames named (base, table, tool, each camera); the task's stage (the
    ``stage`` input) as a state line; each camera (``wrist``, ``left``, ``right``) that the graph
    feeds as a frustum at its calibrated pose with its live video on it (a camera that sends
    nothing is neither drawn nor offered); a transparency slider per camera; buttons that fly the
    viewer into a camera's own view (the video over the model, the report's Figure 16) and
    back to the overview. Stereo snapshots stay in the scene with their frustum and image and
    can be viewed from their own pose; boxes and sketched primitives appear in the model. The
    scene is saved to ``scene_file`` in the run folder on every change and reloads with
    ``load_scene``. The page's address is printed at start.

    A camera's pose: its ``*_pose`` input (the camera's or its mount's pose, in any frame the
    static frames tie to ``world_frame``), else its model's mount in the static frames, and
    for the wrist camera the arm's forward kinematics with the static frames
    flange->tool->camera. Its intrinsics: the ``*_model`` input (zoom changes the frustum),
    else ``wrist_intrinsics`` for the wrist camera.

    Cost: ``step`` only keeps the newest samples; a thread of its own sends at most
    ``max_fps`` updates per second, and nothing at all while no browser is connected.
    """

    TYPE = "View3D"
    Params = View3DParams

    joint_state = Input(
        JointState,
        joints=from_param("joint_names"),
        required=False,
        feedback=True,
        doc="the arm's measured joint angles",
    )
    patch_pose = Input(Pose, required=False, feedback=True, doc="the tool's patch (T_table_patch)")
    wrist_image = Input(Image, required=False, doc="wrist camera video")
    wrist_model = Input(CameraModel, required=False, feedback=True, doc="wrist camera model")
    wrist_pose = Input(Pose, required=False, feedback=True, doc="wrist camera (or mount) pose")
    left_image = Input(Image, required=False, doc="left PTU camera video")
    left_model = Input(CameraModel, required=False, feedback=True, doc="left camera model")
    left_pose = Input(Pose, required=False, feedback=True, doc="left camera (or mount) pose")
    right_image = Input(Image, required=False, doc="right PTU camera video")
    right_model = Input(CameraModel, required=False, feedback=True, doc="right camera model")
    right_pose = Input(Pose, required=False, feedback=True, doc="right camera (or mount) pose")
    snapshot = Input(StereoSnapshot, required=False, doc="stereo snapshots kept in the scene")
    primitive = Input(SketchPrimitive, required=False, doc="sketched points, lines, planes")
    box = Input(SketchBox, required=False, doc="boxes placed by triads")
    objects = Input(
        SceneObjects, required=False, feedback=True, doc="the world's solids (pipe, door, ...)"
    )
    stage = Input(
        Status,
        required=False,
        feedback=True,
        doc="the task's status (vsServo's stage and reason, a world's verdict): the page's "
        "state line",
    )
    status = Output(Status, doc="page address, browsers connected, video frames sent")
    mount = Output(Pose, events=True, doc="the camera mount the pose tool solved and saved")

    # -- lifecycle ------------------------------------------------------------------------------

    def start(self) -> None:
        p = self.params
        for name, values, n in (
            ("wrist_intrinsics", p.wrist_intrinsics, 6),
            ("table_size_m", p.table_size_m, 3),
            ("tray_size_m", p.tray_size_m, 3),
            ("tool_size_m", p.tool_size_m, 3),
            ("overview_xyz_m", p.overview_xyz_m, 3),
            ("overview_target_m", p.overview_target_m, 3),
        ):
            if len(values) != n or not np.all(np.isfinite(values)):
                raise UserError(f"{self.name}: {name} needs {n} finite numbers, got {values}")
        self._pose_tool_frames()  # checked before anything starts
        self._lock = threading.Lock()
        self._latest: dict[str, object] = {}
        self._new_items: list[object] = []
        self._scene = Scene(frame=p.world_frame)
        if p.load_scene:
            self._scene = load_scene(p.load_scene)
            if self._scene.frame != p.world_frame:
                raise UserError(
                    f"{self.name}: scene file {p.load_scene} is in frame {self._scene.frame!r}, "
                    f"the view's world_frame is {p.world_frame!r}"
                )
            self._new_items.extend(self._scene.snapshots.values())
            self._new_items.extend(self._scene.boxes.values())
            self._new_items.extend(self._scene.primitives.values())
        self._scene_path = Path(self.context.output_dir) / p.scene_file
        self._scene_dirty = False
        self._saves = 0
        self._refused = 0
        self._T_world_base = self._lookup(p.world_frame, "base", np.eye(4))
        self._T_flange_tool = self._lookup("flange", p.tool_frame, None)
        self._T_tool_wrist = self._lookup(p.tool_frame, p.wrist_frame, None)
        self._T_world_table = (
            self._lookup(p.world_frame, p.table_frame, None) if p.table_frame else None
        )
        overview = viewer_pose_looking_at(
            p.overview_xyz_m, p.overview_target_m, np.radians(p.overview_fov_deg)
        )
        try:
            self.page = ViewerPage(
                p.host,
                p.port,
                overview,
                CAMERAS,
                p.video_width,
                animation_s=p.animation_s,
                token=resolve_token(p.token_file, self.name),
            )
        except OSError as error:
            raise UserError(
                f"{self.name}: cannot serve the 3-D view on {p.host}:{p.port}: {error.strerror}"
            ) from None
        self.page.on_save = self.save_now
        self.page.on_snapshot = self._snapshot_taken
        self._start_pose_tool()
        self.address = self.page.address
        print(f"3-D view: {self.address}", flush=True)
        self.log.info("3-D view at %s", self.address)
        self._draw_static(None)
        self._sent_frames = 0
        self._updates = 0
        self._skipped_idle = 0
        self._shown: dict[str, object] = {}  # the samples on the page now, by input
        self._failed = 0  # parts of updates that failed (malformed samples)
        self._warned: set[str] = set()
        self._stopping = threading.Event()
        self._thread = threading.Thread(
            target=self._pusher, name=f"{self.name}-view3d", daemon=True
        )
        self._thread.start()

    def stop(self) -> None:
        if getattr(self, "_thread", None) is not None:
            self._stopping.set()
            self._thread.join(timeout=5.0)
        pending = getattr(self, "_new_items", None)
        if pending:  # arrived after the sender's last turn: keep them too
            for item in pending:
                kind = {"SceneSnapshot": "snapshots", "SceneBox": "boxes"}.get(
                    type(item).__name__, "primitives"
                )
                getattr(self._scene, kind)[item.id] = item
            self._scene_dirty = True
        if getattr(self, "_scene_dirty", False):
            self._save()
        if getattr(self, "page", None) is not None:
            self.page.stop()

    def summary(self) -> dict[str, object]:
        return {
            "address": getattr(self, "address", "").split("?")[0],  # not the token: a file
            "refused_requests": self.page.door.refused if getattr(self, "page", None) else 0,
            "updates_sent": getattr(self, "_updates", 0),
            "video_frames_sent": {k: s.frames_sent for k, s in self.page.cameras.items()}
            if getattr(self, "page", None) is not None
            else {},
            "scene_items": self._scene.count() if hasattr(self, "_scene") else 0,
            "items_refused": getattr(self, "_refused", 0),
            "update_parts_failed": getattr(self, "_failed", 0),
            "scene_file": str(getattr(self, "_scene_path", "")),
        }

    def _pose_tool_frames(self) -> tuple[str, str]:
        parent, sep, child = self.params.pose_tool_mount.partition("->")
        if not sep or not parent.strip() or not child.strip():
            raise UserError(
                f"{self.name}: pose_tool_mount must be written parent->child, got "
                f"{self.params.pose_tool_mount!r}"
            )
        return parent.strip(), child.strip()

    def _start_pose_tool(self) -> None:
        parent, child = self._pose_tool_frames()
        T_nominal = self._lookup(parent, child, None)
        if T_nominal is None:
            self.log.warning(
                "pose tool: no static frame %s->%s; the mount is solved starting from the identity",
                parent,
                child,
            )
            T_nominal = np.eye(4)
        # a parent the static frames tie to the world stays put (a PTU's base); else it moves
        T_world_parent = self._lookup(self.params.world_frame, parent, None)
        tool = PoseTool(parent, child, T_nominal, snapshot_image_depth(self.page), T_world_parent)
        self._mounts: list[np.ndarray] = []
        self.pose_tool = PoseToolWidgets(
            self.page, tool, Path(self.context.output_dir), self._mount_saved
        )

    def _mount_saved(self, T_parent_child: np.ndarray) -> None:
        with self._lock:  # called on the page's thread; step sends it
            self._mounts.append(np.array(T_parent_child))

    def _snapshot_taken(self, snapshot) -> None:
        with self._lock:
            self._new_items.append(snapshot)

    def _lookup(self, parent: str, child: str, default):
        frames = self.context.frames
        if parent == child:
            return np.eye(4)
        if frames.has(parent, child):
            return frames.lookup(parent, child)
        return default

    # -- step: keep the newest samples (cheap; never blocks) ------------------------------------

    def step(self, now: float) -> None:
        latest = {}
        for port in (
            "joint_state",
            "patch_pose",
            "objects",
            "stage",
            *(f"{c}_{k}" for c in CAMERAS for k in ("image", "model", "pose")),
        ):
            sample = getattr(self, port).get(now)
            if sample is not None:
                latest[port] = sample
        items = []
        try:
            if self.snapshot.fresh and (s := self.snapshot.get(now)) is not None:
                items.extend(snapshot_items(s, self._to_world(s.frame)))
            if self.primitive.fresh and (s := self.primitive.get(now)) is not None:
                items.append(primitive_item(s, self._to_world(s.frame)))
            if self.box.fresh and (s := self.box.get(now)) is not None:
                items.append(box_item(s, self._to_world(s.frame)))
        except ValueError as error:  # a malformed item is refused, the view goes on
            self._refused += 1
            self.log.warning("3-D view refused a sketch item: %s", error)
        with self._lock:
            self._latest = latest
            self._new_items.extend(items)
            mounts, self._mounts = self._mounts, []
        for T in mounts:
            tool = self.pose_tool.tool
            self.mount.send(Pose(matrix=T, parent=tool.parent, child=tool.child))
        if self.page is not None and now - getattr(self, "_status_at", -np.inf) >= 1.0:
            self._status_at = now
            self.status.send(
                Status(
                    stage="serving",
                    message=self.address.split("?")[0],  # not the token: it travels
                    values={
                        "browsers": float(self.page.clients()),
                        "updates_sent": float(self._updates),
                    },
                )
            )

    def _to_world(self, frame: str) -> np.ndarray:
        T = self._lookup(self.params.world_frame, frame, None)
        if T is None:
            raise UserError(
                f"{self.name}: a sketch item is in frame {frame!r}, which the static frames do "
                f"not tie to the view's world_frame {self.params.world_frame!r}"
            )
        return T
