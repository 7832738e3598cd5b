"""View3D: the live 3-D view of the workcell (LDRD report section 4), served beside the console."""

from __future__ import annotations

import threading
from pathlib import Path
from typing import overload

import numpy as np
from pydantic import field_validator, model_validator

from umbra.connectors import Input, Module, Output, ParamProblem, UserError, from_param, param
from umbra.connectors.access.hosts import MAX_TCP_PORT
from umbra.connectors.access.secret import resolve_token
from umbra.connectors.limits import MIN_RATE_HZ
from umbra.connectors.messages import CameraModel, Image, JointState, Pose, Status
from umbra.connectors.params import RunFile
from umbra.connectors.scene_messages import SceneObjects
from umbra.connectors.sketch_messages import SketchBox, SketchPrimitive, StereoSnapshot
from umbra.connectors.states import Verdict
from umbra.modules.arm.arm_params import ArmParams
from umbra.modules.view3d.geometry import (
    viewer_pose_looking_at,
)
from umbra.modules.view3d.pose_tool_panel import PoseTool
from umbra.modules.view3d.pose_tool_widgets import PoseToolWidgets, snapshot_image_depth
from umbra.modules.view3d.scene_file import Scene, load_scene
from umbra.modules.view3d.scene_messages import box_item, primitive_item, snapshot_items
from umbra.modules.view3d.view3d_push import CAMERAS, SceneItem, ViewPush, verdict_words
from umbra.modules.view3d.viewer import ViewerPage
from umbra.modules.webdoor.linger import END_LINGER_S, linger


class View3DParams(ArmParams):
    """Parameters of the 3-D view (the arm's DH table comes from ArmParams)."""

    host: str = param("127.0.0.1", "address the page listens on (loopback by default)")
    port: int = param(8090, "TCP port of the page; 0: any free port", ge=0, le=MAX_TCP_PORT)
    token_file: str = param(
        "", "file whose first line is the page's access token (else a random one, printed)"
    )
    world_frame: str = param("base", "the view's reference frame (z up)")
    max_fps: float = param(
        10.0,
        "most scene updates (video frames) sent per second",
        unit="Hz",
        ge=MIN_RATE_HZ,  # the scheduler's slowest rate: below it a wait overflows the OS's time
        le=60,
    )
    video_width: int = param(
        320, "video is scaled down to this width for the page", unit="px", ge=32, le=1920
    )
    wrist_intrinsics: list[float] = param(
        [800.0, 800.0, 640.0, 360.0, 1280.0, 720.0],
        "wrist camera fx fy u0 v0 width height without a wrist_model input",
        unit="px",
        min_length=6,
        max_length=6,
    )
    wrist_frame: str = param("camera", "the wrist camera's frame in the static frames")
    tool_frame: str = param("tool", "frame the arm's tool is (static frame below flange)")
    table_frame: str = param("table", "the table top's frame (z up); '' for no table")
    table_size_m: list[float] = param(
        [1.4, 1.2, 0.04], "table x, y, thickness", unit="m", min_length=3, max_length=3
    )
    tray_size_m: list[float] = param(
        [0.3, 0.22, 0.01], "tray under the tool x, y, z", unit="m", min_length=3, max_length=3
    )
    tool_size_m: list[float] = param(
        [0.08, 0.05, 0.03], "tool body x, y, height", unit="m", min_length=3, max_length=3
    )
    overview_xyz_m: list[float] = param(
        [1.9, -1.6, 1.4], "overview viewer position", unit="m", min_length=3, max_length=3
    )
    overview_target_m: list[float] = param(
        [0.45, 0.0, 0.3], "overview look-at point", unit="m", min_length=3, max_length=3
    )
    overview_fov_deg: float = param(
        50.0, "overview vertical field of view", unit="deg", gt=1, lt=170
    )
    animation_s: float = param(1.0, "duration of a viewer move", unit="s", ge=0, le=10)
    scene_file: RunFile = param("scene.json", "scene file in the run folder, saved on every change")
    load_scene: str = param("", "scene file to load at start (a previous run's)")
    pose_tool_mount: str = param(
        "tool->camera", "the static frame parent->child the pose tool corrects (a camera mount)"
    )

    @field_validator("pose_tool_mount")
    @classmethod
    def _parent_child(cls, value: str) -> str:
        parent, sep, child = value.partition("->")
        if not sep or not parent.strip() or not child.strip():
            raise ValueError(f"must be written parent->child, found {value!r}")
        return value

    @model_validator(mode="after")
    def _scene_in_world_frame(self) -> View3DParams:
        """A scene to load is a scene file, in the view's frame."""
        if self.load_scene:
            try:
                frame = load_scene(self.load_scene).frame
            except UserError as exc:
                raise ParamProblem("load_scene", f"cannot be loaded: {exc}") from None
            if frame != self.world_frame:
                raise ParamProblem(
                    "load_scene",
                    f"is a scene in frame {frame!r}; expected the view's world_frame "
                    f"{self.world_frame!r}",
                )
        return self


class View3D(Module[View3DParams]):
    """The live 3-D view: the arm from its DH table moving with the joint state; the table,
    tray and tool, the frames named (base, table, tool, each camera); the task's stage (the
    ``stage`` input) as a state line; each camera (``wrist``, ``left``, ``right``) that the graph
    feeds as a frustum at its calibrated pose with its live video on it (a camera that sends
    nothing is neither drawn nor offered); a transparency slider per camera; buttons that fly the
    viewer into a camera's own view (the video over the model, the report's Figure 16) and
    back to the overview. Stereo snapshots stay in the scene with their frustum and image and
    can be viewed from their own pose; boxes and sketched primitives appear in the model. The
    scene is saved to ``scene_file`` in the run folder on every change and reloads with
    ``load_scene``. The page's address is printed at start. A judge's ``verdict`` is said under
    the state line; at the run's end the page says that it ended, with the verdict (in the
    panel's header too, which keeps it once the server is gone), and the server serves on until
    the process ends (:mod:`umbra.modules.webdoor.linger`): a page that reconnects then still
    learns how the run ended.

    A camera's pose: its ``*_pose`` input (the camera's or its mount's pose, in any frame the
    static frames tie to ``world_frame``), else its model's mount in the static frames, and
    for the wrist camera the arm's forward kinematics with the static frames
    flange->tool->camera. Its intrinsics: the ``*_model`` input (zoom changes the frustum),
    else ``wrist_intrinsics`` for the wrist camera.

    Cost: ``step`` only keeps the newest samples; a thread of its own sends at most
    ``max_fps`` updates per second, none before every browser has applied the one before
    (:mod:`~umbra.modules.view3d.viewer_pace`), and nothing at all while no browser is
    connected.
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
    verdict = Input(
        Verdict,
        required=False,
        feedback=True,
        doc="a judge's verdict on the run (the world's): said on the page once judged, and with "
        "the run's end",
    )
    status = Output(Status, doc="page address, browsers connected, video frames sent")
    mount = Output(Pose, events=True, doc="the camera mount the pose tool solved and saved")

    # -- lifecycle ------------------------------------------------------------------------------

    def start(self) -> None:
        p = self.params
        self._lock = threading.Lock()
        scene = Scene(frame=p.world_frame)
        if p.load_scene:
            scene = load_scene(p.load_scene)  # read and judged by View3DParams
        self.push = ViewPush(self, self._lock, scene, Path(self.context.output_dir) / p.scene_file)
        self.push.new_items.extend(scene.snapshots.values())
        self.push.new_items.extend(scene.boxes.values())
        self.push.new_items.extend(scene.primitives.values())
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
        self.page.on_save = self.push.save_now
        self.page.on_snapshot = self.push.add_item
        self._start_pose_tool()
        self.address = self.page.address
        print(f"3-D view: {self.address}", flush=True)
        self.log.info("3-D view at %s", self.address)
        self.push.draw_static(None)
        self.push.start()

    def stop(self) -> None:
        page = getattr(self, "page", None)
        if page is not None:
            # the run's end and its verdict, said first (the sender's last turn and the scene's
            # save come after), stay on the page (its header too, where viser would say
            # "Connecting..." once the server is gone); a page that reconnects meanwhile gets
            # them from the server, which serves on until the process ends
            page.end(verdict_words(self.verdict.value))
        push: ViewPush | None = getattr(self, "push", None)
        if push is not None:
            push.stop()
        if page is not None:
            linger(page.stop, END_LINGER_S, f"{self.name}-linger")

    def summary(self) -> dict[str, object]:
        push: ViewPush | None = getattr(self, "push", None)
        return {
            "address": getattr(self, "address", "").split("?")[0],  # not the token: a file
            "refused_requests": self.page.door.refused if getattr(self, "page", None) else 0,
            "updates_sent": 0 if push is None else push.updates,
            "updates_held": 0 if push is None else push.held,
            "video_frames_sent": {k: s.frames_sent for k, s in self.page.cameras.items()}
            if getattr(self, "page", None) is not None
            else {},
            "scene_items": 0 if push is None else push.scene.count(),
            "items_refused": getattr(self, "_refused", 0),
            "update_parts_failed": 0 if push is None else push.failed,
            "scene_file": "" if push is None else str(push.scene_path),
        }

    def _pose_tool_frames(self) -> tuple[str, str]:
        parent, _, child = self.params.pose_tool_mount.partition("->")  # View3DParams: a -> b
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

    @overload
    def _lookup(self, parent: str, child: str, default: np.ndarray) -> np.ndarray: ...
    @overload
    def _lookup(self, parent: str, child: str, default: None) -> np.ndarray | None: ...
    def _lookup(self, parent: str, child: str, default: np.ndarray | None) -> np.ndarray | None:
        """T_parent_child from the static frames (the identity for one frame); ``default``
        when they do not tie the two."""
        frames = self.context.frames
        if parent == child:
            return np.eye(4)
        if frames.has(parent, child):
            return frames.lookup(parent, child)
        return default

    # -- step: keep the newest samples (cheap; never blocks) ------------------------------------

    def step(self, now: float) -> None:
        latest: dict[str, object] = {}
        for port in (
            "joint_state",
            "patch_pose",
            "objects",
            "stage",
            "verdict",
            *(f"{c}_{k}" for c in CAMERAS for k in ("image", "model", "pose")),
        ):
            sample = getattr(self, port).get(now)
            if sample is not None:
                latest[port] = sample
        items: list[SceneItem] = []
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
            self.push.latest = latest
            self.push.new_items.extend(items)
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
                        "updates_sent": float(self.push.updates),
                        "updates_held": float(self.push.held),
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
