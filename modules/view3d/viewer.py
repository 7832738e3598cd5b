"""The 3-D view's web page, served by viser: the workcell, the arm, camera frusta with live
video, snapshots and sketched geometry, a transparency slider per camera, and the buttons that
move the viewer between a camera's own view (the report's Figure 16) and the overview.

Why viser: it draws an image on a camera frustum, lets Python read and set each browser's
camera (needed for "camera view" and for testing it to 1 mm / 0.1 deg), and reports scene clicks
as rays (the pose tool's picking), with no hand-written JavaScript. Rerun shows pinhole images
in 3-D well but cannot take the operator's clicks; NiceGUI's three.js scene would need our own
texture and camera code. Transparency: viser has no image opacity, but its frustum image
material is transparent, so the video is sent as RGBA (alpha = the slider) while it is not
opaque, and as JPEG when it is.

This class knows nothing of the graph: the View3D module hands it geometry and images from its
own thread. Every method may be called from any thread (viser queues the messages); a newer
update of the same scene property replaces an unsent older one in viser's outgoing buffer. That
alone does not keep a slow browser from a backlog (its socket reads on while its page is busy):
:attr:`ViewerPage.pace` says when every browser has applied the last update, and the sender
waits for it.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import viser
from viser import FrameHandle, LabelHandle, LineSegmentsHandle, PointCloudHandle

from umbra.connectors.access.secret import TOKEN_QUERY
from umbra.connectors.scene_messages import SolidKind
from umbra.modules.view3d.geometry import (
    Frustum,
    Mesh,
    ViewerPose,
    box_mesh,
    cylinder_mesh,
    solid_pose,
    wxyz_from_matrix,
)
from umbra.modules.view3d.scene_file import SceneSnapshot
from umbra.modules.view3d.viewer_moves import ViewerMoves
from umbra.modules.view3d.viewer_pace import BrowserPace
from umbra.modules.view3d.viewer_sketch import ViewerSketch
from umbra.modules.view3d.viewer_video import (
    CAMERA_COLORS,
    FRUSTUM_SCALES,
    node_name,
    video_rgba,
)
from umbra.modules.view3d.viser_door import guard_viser


@dataclass
class CameraState:
    """What the page shows of one live camera: its frustum, the opacity of its video, and the
    counters of frames sent."""

    name: str
    frustum: Frustum | None = None
    handle: object | None = None
    opacity: float = 1.0
    frames_sent: int = 0
    channels: int | None = None
    last_image: np.ndarray | None = field(default=None, repr=False)


class ViewerPage(ViewerMoves, ViewerSketch):
    """The viser server and its scene (see the module docstring)."""

    def __init__(
        self,
        host: str,
        port: int,
        overview: ViewerPose,
        cameras: tuple[str, ...] = ("wrist", "left", "right"),
        video_width: int = 320,
        jpeg_quality: int = 80,
        animation_s: float = 1.0,
        token: str = "",
    ) -> None:
        """``token``: the per-run access token every request and socket needs (required)."""
        if not token:
            raise ValueError("the 3-D view needs an access token")
        self.server = viser.ViserServer(host=host, port=port, verbose=False)
        self.token = token
        self.door = guard_viser(self.server.get_port(), token, host)
        #: whether the browsers have applied the last update (the sender waits for them)
        self.pace = BrowserPace(self.server)
        self.overview = overview
        self.video_width = video_width
        self.jpeg_quality = jpeg_quality
        self.animation_s = animation_s
        self._lock = threading.Lock()
        self.cameras = {name: CameraState(name) for name in cameras}
        self.snapshots: dict[str, tuple[SceneSnapshot, Frustum]] = {}
        self.meshes: dict[str, Mesh] = {}  #: the model's surfaces, by scene node name
        #: the frames' names written in the model: label -> (text, position in the world, m)
        self.labels: dict[str, tuple[str, np.ndarray]] = {}
        self.labels_sent = 0
        self._label_nodes: dict[str, LabelHandle] = {}
        #: the arm's nodes once drawn: its links and its joints, and its tool frame
        self._arm: tuple[LineSegmentsHandle, PointCloudHandle] | None = None
        self._arm_tool: FrameHandle | None = None
        #: per browser (viser client id): the number of its latest viewer move, and the live
        #: camera its viewer rides with after "View from ..."
        self._generation: dict[int, int] = {}
        self._following: dict[int, str] = {}
        self._moving: set[int] = set()
        self.on_save: Callable[[], str] | None = None
        #: called with a new snapshot taken by a button (the module keeps it in its scene)
        self.on_snapshot: Callable[[SceneSnapshot], None] | None = None
        self._taken = 0
        self.ended = ""  #: the verdict said at the run's end ("" while the run lives)
        self._stopped = False
        self._build_gui()
        self.server.scene.set_up_direction("+z")
        # plain lights, no environment map or shadows: cheap to draw on any machine (a browser
        # with software WebGL spends seconds building an environment map)
        self.server.scene.configure_environment_map(hdri=None)
        self.server.scene.configure_default_lights(enabled=True, cast_shadow=False)
        self.server.initial_camera.position = tuple(overview.position)
        self.server.initial_camera.look_at = tuple(overview.look_at)
        self.server.initial_camera.up = (0.0, 0.0, 1.0)
        self.server.initial_camera.fov = overview.fov_y

    @property
    def address(self) -> str:
        """The page's address with its token (bound to every interface: the loopback one)."""
        host = {"0.0.0.0": "127.0.0.1", "::": "::1", "": "127.0.0.1"}.get(
            self.server.get_host(), self.server.get_host()
        )
        host = f"[{host}]" if ":" in host else host
        return f"http://{host}:{self.server.get_port()}/?{TOKEN_QUERY}={self.token}"

    def clients(self) -> int:
        return len(self.server.get_clients())

    def stop(self) -> None:
        """Stop the server (once: the run's end and the process's end may both ask)."""
        if not self._stopped:
            self._stopped = True
            self.pace.stop()
            self.server.stop()

    # -- GUI ------------------------------------------------------------------------------------

    def _build_gui(self) -> None:
        gui = self.server.gui
        gui.configure_theme(control_width="medium", show_share_button=False)
        gui.main_panel.dock_right()
        self.overview_button = gui.add_button("Overview")
        self.overview_button.on_click(lambda event: self.animate_to(event.client, self.overview))
        self.stage_note = gui.add_markdown("**stage**: (no task status wired)")
        self.verdict_note = gui.add_markdown("")
        self.sliders: dict[str, object] = {}
        self.view_buttons: dict[str, object] = {}
        with gui.add_folder("Snapshots"):
            self.snapshot_dropdown = gui.add_dropdown("snapshot", options=("(none)",))
            self.snapshot_button = gui.add_button("View from snapshot")
            self.save_button = gui.add_button("Save scene")
            self.save_note = gui.add_markdown("")
        self.snapshot_button.on_click(
            lambda event: self.view_from_snapshot(event.client, str(self.snapshot_dropdown.value))
        )
        self.save_button.on_click(lambda _event: self._save_clicked())

    def _camera_gui(self, name: str) -> None:
        """A camera's folder (opacity, View from, Snapshot), added when it first shows: the page
        offers only the cameras the graph feeds it. Call with ``self._lock`` held."""
        if name in self.sliders:
            return
        gui = self.server.gui
        with gui.add_folder(f"Camera {name}"):
            slider = gui.add_slider("video opacity", min=0.0, max=1.0, step=0.05, initial_value=1.0)
            button = gui.add_button(f"View from {name}")
            take = gui.add_button(f"Snapshot {name}")
        take.on_click(lambda _event, n=name: self.take_snapshot(n))
        slider.on_update(lambda _event, n=name, s=slider: self.set_opacity(n, float(s.value)))
        button.on_click(lambda event, n=name: self.view_from_camera(event.client, n))
        self.sliders[name] = slider
        self.view_buttons[name] = button

    def set_stage(self, text: str) -> None:
        """The task's state line (the stage and what it is doing), shown above the cameras;
        once the run has ended (:meth:`end`) the line keeps saying so."""
        if not self.ended:
            self.stage_note.content = f"**stage**: {text}"

    def set_verdict(self, text: str) -> None:
        """The judge's verdict on the run ("" none yet), shown under the state line; once the
        run has ended (:meth:`end`) the line keeps the verdict it ended with."""
        if not self.ended:
            self._show_verdict(text)

    def _show_verdict(self, text: str) -> None:
        self.verdict_note.content = f"**verdict**: {text}" if text else ""

    def end(self, verdict: str) -> None:
        """The run has ended with ``verdict`` (its words): said under the state line and in the
        panel's header, which keeps saying it once the server is gone (instead of viser's
        "Connecting..."). What the run's last updates would still say is not shown after it."""
        self.ended = verdict
        self.stage_note.content = "**the run has ended**: this page is no longer live"
        self._show_verdict(verdict)
        self.server.gui.set_panel_label(f"Run ended: {verdict}")

    def label(self, name: str, text: str, T_world_frame: np.ndarray) -> None:
        """A frame's name written at its origin in the model (``labels``: where each is); sent
        to the browsers only when its text or place changed (``labels_sent`` counts them)."""
        at = np.array(T_world_frame[:3, 3], dtype=float)
        shown = self.labels.get(name)
        if shown is not None and shown[0] == text and np.array_equal(shown[1], at):
            return
        self.labels[name] = (text, at)
        self.labels_sent += 1
        handle = self._label_nodes.get(name)
        if handle is None:  # made once, then moved (as the arm's nodes)
            self._label_nodes[name] = self.server.scene.add_label(
                f"/labels/{node_name(name)}", text=text, position=tuple(at)
            )
            return
        if shown is None or shown[0] != text:
            handle.text = text
        handle.position = at

    def _save_clicked(self) -> None:
        if self.on_save is not None:
            self.save_note.content = f"saved {self.on_save()}"

    # -- the workcell and the arm ---------------------------------------------------------------

    def add_box(
        self,
        name: str,
        T_world_box: np.ndarray,
        size: np.ndarray,
        color: tuple[int, int, int],
        opacity: float | None = None,
    ) -> None:
        self.meshes[name] = box_mesh(name, T_world_box, size)  # for picking points by clicks
        self.server.scene.add_box(
            name,
            dimensions=tuple(float(v) for v in size),
            color=color,
            wxyz=wxyz_from_matrix(T_world_box[:3, :3]),
            position=tuple(T_world_box[:3, 3]),
            opacity=opacity,
        )

    def set_objects(self, names, kinds, poses, sizes, colors) -> list[str]:
        """The world's solids (Active Sketch's scene objects): boxes and cylinders. Returns the
        names of the solids it could not draw (a pose that is not a rotation or reflection, a
        size that is not positive and finite); the others are drawn all the same."""
        refused = []
        for name, kind, pose, size, color in zip(names, kinds, poses, sizes, colors, strict=True):
            node = f"/objects/{node_name(name)}"
            T = solid_pose(pose)
            size = np.asarray(size, dtype=float)
            if T is None or not (np.all(np.isfinite(size)) and np.all(size > 0)):
                refused.append(str(name))
                continue
            red, green, blue = (int(c) for c in color)  # colors are N x 3 (SceneObjects)
            rgb = (red, green, blue)
            if kind == SolidKind.CYLINDER:
                self.meshes[node] = cylinder_mesh(node, T, float(size[0]), float(size[2]))
                self.server.scene.add_cylinder(
                    node,
                    radius=float(size[0]),
                    height=float(size[2]),
                    color=rgb,
                    wxyz=wxyz_from_matrix(T[:3, :3]),
                    position=tuple(T[:3, 3]),
                )
            else:  # SolidKind.BOX: SceneObjects holds SolidKinds only
                self.add_box(node, T, size, rgb)
        return refused

    def set_arm(
        self, segments: np.ndarray, joints: np.ndarray, T_world_tool: np.ndarray | None
    ) -> None:
        """Draw the arm's links (``(m, 2, 3)`` segments, m), its joints ``(n, 3)`` and its tool
        frame. The nodes are made once (again only when the arm's shape changes) and then
        moved by property updates: a node made anew costs the browser a new shader program
        per update for the joints (measured: ten programs linked a second at 10 updates/s,
        a frame of the page 67 ms instead of 17 ms with software WebGL)."""
        links = segments.astype(np.float32)
        points = joints.astype(np.float32)
        arm = self._arm
        if arm is None or arm[0].points.shape != links.shape or arm[1].points.shape != points.shape:
            colors = np.broadcast_to(np.array([90, 90, 110], dtype=np.uint8), links.shape)
            arm = (
                self.server.scene.add_line_segments(
                    "/arm/links",
                    points=links,
                    colors=colors,
                    thickness=8.0,
                    thickness_units="screen",
                ),
                self.server.scene.add_point_cloud(
                    "/arm/joints",
                    points=points,
                    colors=(40, 40, 40),
                    point_size=0.03,
                    point_shape="circle",
                ),
            )
            self._arm = arm
        else:
            arm[0].points = links
            arm[1].points = points
        if T_world_tool is not None:
            wxyz = wxyz_from_matrix(T_world_tool[:3, :3])
            if self._arm_tool is None:
                self._arm_tool = self.server.scene.add_frame(
                    "/arm/tool",
                    wxyz=wxyz,
                    position=tuple(T_world_tool[:3, 3]),
                    axes_length=0.06,
                    axes_radius=0.004,
                )
            else:
                self._arm_tool.wxyz = wxyz
                self._arm_tool.position = T_world_tool[:3, 3].copy()

    # -- live cameras ---------------------------------------------------------------------------

    def set_opacity(self, name: str, opacity: float) -> None:
        """The transparency slider: re-send the last frame with the new alpha at once."""
        state = self.cameras[name]
        state.opacity = float(np.clip(opacity, 0.0, 1.0))
        self.refresh_image(name)

    def set_camera(
        self,
        name: str,
        frustum: Frustum,
        image_bgr: np.ndarray | None,
        force_image: bool = False,
    ) -> None:
        """Place a live camera's frustum and, when given, show its newest image.

        The frustum node is created once (and again only when the field of view changes, as
        when zooming); a pose or an image is then sent as a property update of that node, so
        the browser keeps the node and its texture while the next frame loads.
        """
        state = self.cameras[name]
        with self._lock:
            previous = state.frustum
            state.frustum = frustum
            if image_bgr is not None:
                state.last_image = image_bgr
            channels = None
            if state.last_image is not None:
                channels = 3 if state.opacity >= 1.0 else 4  # as video_rgba makes it
            # a new node when the field of view changes (zoom) or the image's kind changes
            # (JPEG while opaque, PNG with alpha while not): viser keeps a node's format
            shape_changed = (
                previous is None
                or state.handle is None
                or channels != state.channels
                or not np.isclose(previous.fov_y, frustum.fov_y, rtol=0, atol=1e-9)
                or not np.isclose(previous.aspect, frustum.aspect, rtol=0, atol=1e-9)
            )
            state.channels = channels
            pixels = None
            if channels is not None and (image_bgr is not None or shape_changed or force_image):
                pixels = video_rgba(state.last_image, state.opacity, self.video_width)
            wxyz = wxyz_from_matrix(frustum.T_world_camera[:3, :3])
            position = frustum.T_world_camera[:3, 3].copy()
            if shape_changed:
                self._camera_gui(name)
                state.handle = self.server.scene.add_camera_frustum(
                    f"/cameras/{name}",
                    fov=frustum.fov_y,
                    aspect=frustum.aspect,
                    scale=FRUSTUM_SCALES.get(name, 0.15),
                    thickness=2.0,
                    thickness_units="screen",
                    color=CAMERA_COLORS.get(name, (200, 60, 60)),
                    image=pixels,
                    format="auto",  # RGB as JPEG, RGBA (not opaque) as PNG
                    jpeg_quality=self.jpeg_quality,
                    wxyz=wxyz,
                    position=tuple(position),
                )
            else:
                handle = state.handle
                if previous is None or not np.array_equal(
                    previous.T_world_camera, frustum.T_world_camera
                ):
                    handle.wxyz = wxyz
                    handle.position = position
                if pixels is not None:
                    handle.image = pixels
            if pixels is not None and image_bgr is not None:
                state.frames_sent += 1
            moved = previous is None or not np.array_equal(
                previous.T_world_camera, frustum.T_world_camera
            )
            moved = moved or not np.isclose(previous.fov_y, frustum.fov_y, rtol=0, atol=1e-9)
        if moved:
            self._move_followers(name)

    def refresh_image(self, name: str) -> None:
        """Send the last image again (after an opacity change)."""
        state = self.cameras[name]
        if state.frustum is not None and state.last_image is not None:
            self.set_camera(name, state.frustum, None, force_image=True)

    def take_snapshot(self, name: str) -> SceneSnapshot | None:
        """Keep a live camera's current image at its current pose as a snapshot."""
        state = self.cameras[name]
        with self._lock:
            if state.frustum is None or state.last_image is None:
                return None
            self._taken += 1
            frustum, image = state.frustum, np.array(state.last_image)
        snapshot = SceneSnapshot(
            f"{name}-{self._taken}", name, frustum.T_world_camera.copy(), frustum.K.copy(), image
        )
        if self.on_snapshot is not None:
            self.on_snapshot(snapshot)
        return snapshot
