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
update of the same scene property replaces an unsent older one in viser's outgoing buffer, so a
slow browser gets the newest frame, never a backlog.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import cv2
import numpy as np
import viser

from modules.view3d.geometry import (
    Frustum,
    Mesh,
    ViewerPose,
    box_mesh,
    cylinder_mesh,
    interpolate_viewer,
    solid_pose,
    viewer_pose_from_camera,
    wxyz_from_matrix,
)
from modules.view3d.scene_file import SceneBox, ScenePrimitive, SceneSnapshot

#: size of a live camera's frustum (viser's volume-normalized scale, m); the wrist camera's is
#: small so that its image lies in front of the gripper it looks past
FRUSTUM_SCALES = {"wrist": 0.05, "left": 0.15, "right": 0.15}
SNAPSHOT_SCALE = 0.2  #: size of a snapshot's frustum
CAMERA_COLORS = {"wrist": (230, 120, 20), "left": (20, 120, 230), "right": (20, 170, 90)}


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


def video_rgba(image_bgr: np.ndarray, opacity: float, max_width: int) -> np.ndarray:
    """The image as the page draws it: at most ``max_width`` wide, RGB, plus an alpha channel
    of ``opacity`` (0 transparent .. 1 opaque) when it is not opaque."""
    h, w = image_bgr.shape[:2]
    if w > max_width:
        image_bgr = cv2.resize(
            image_bgr, (max_width, max(1, round(h * max_width / w))), interpolation=cv2.INTER_AREA
        )
    if opacity >= 1.0:
        return cv2.cvtColor(image_bgr, cv2.COLOR_BGR2RGB)
    rgba = cv2.cvtColor(image_bgr, cv2.COLOR_BGR2RGBA)
    rgba[..., 3] = round(255 * max(0.0, opacity))
    return rgba


class ViewerPage:
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
    ) -> None:
        self.server = viser.ViserServer(host=host, port=port, verbose=False)
        self.overview = overview
        self.video_width = video_width
        self.jpeg_quality = jpeg_quality
        self.animation_s = animation_s
        self._lock = threading.Lock()
        self.cameras = {name: CameraState(name) for name in cameras}
        self.snapshots: dict[str, tuple[SceneSnapshot, Frustum]] = {}
        self.meshes: dict[str, Mesh] = {}  #: the model's surfaces, by scene node name
        #: per browser (viser client id): the number of its latest viewer move, and the live
        #: camera its viewer rides with after "View from ..."
        self._generation: dict[int, int] = {}
        self._following: dict[int, str] = {}
        self._moving: set[int] = set()
        self.on_save: Callable[[], str] | None = None
        #: called with a new snapshot taken by a button (the module keeps it in its scene)
        self.on_snapshot: Callable[[SceneSnapshot], None] | None = None
        self._taken = 0
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
        return f"http://{self.server.get_host()}:{self.server.get_port()}/"

    def clients(self) -> int:
        return len(self.server.get_clients())

    def stop(self) -> None:
        self.server.stop()

    # -- GUI ------------------------------------------------------------------------------------

    def _build_gui(self) -> None:
        gui = self.server.gui
        gui.configure_theme(control_width="medium", show_share_button=False)
        gui.main_panel.dock_right()
        self.overview_button = gui.add_button("Overview")
        self.overview_button.on_click(lambda event: self.animate_to(event.client, self.overview))
        self.sliders: dict[str, object] = {}
        self.view_buttons: dict[str, object] = {}
        for name in self.cameras:
            with gui.add_folder(f"Camera {name}"):
                slider = gui.add_slider(
                    "video opacity", min=0.0, max=1.0, step=0.05, initial_value=1.0
                )
                button = gui.add_button(f"View from {name}")
                take = gui.add_button(f"Snapshot {name}")
            take.on_click(lambda _event, n=name: self.take_snapshot(n))
            slider.on_update(lambda _event, n=name, s=slider: self.set_opacity(n, float(s.value)))
            button.on_click(lambda event, n=name: self.view_from_camera(event.client, n))
            self.sliders[name] = slider
            self.view_buttons[name] = button
        with gui.add_folder("Snapshots"):
            self.snapshot_dropdown = gui.add_dropdown("snapshot", options=("(none)",))
            self.snapshot_button = gui.add_button("View from snapshot")
            self.save_button = gui.add_button("Save scene")
            self.save_note = gui.add_markdown("")
        self.snapshot_button.on_click(
            lambda event: self.view_from_snapshot(event.client, str(self.snapshot_dropdown.value))
        )
        self.save_button.on_click(lambda _event: self._save_clicked())

    def _save_clicked(self) -> None:
        if self.on_save is not None:
            self.save_note.content = f"saved {self.on_save()}"

    # -- the viewer's camera --------------------------------------------------------------------

    def set_viewer(self, client: viser.ClientHandle, pose: ViewerPose) -> None:
        """Put one browser's camera at ``pose`` at once."""
        with client.atomic():
            client.camera.fov = pose.fov_y
            client.camera.position = pose.position
            client.camera.look_at = pose.look_at
            client.camera.up_direction = pose.up

    def current_viewer(self, client: viser.ClientHandle) -> ViewerPose:
        cam = client.camera
        from modules.view3d.geometry import matrix_from_wxyz

        R = matrix_from_wxyz(cam.wxyz)
        return ViewerPose(
            np.array(cam.position),
            np.array(cam.wxyz),
            float(cam.fov),
            np.array(cam.look_at),
            -R[:, 1],
        )

    def animate_to(
        self,
        client: viser.ClientHandle,
        target: ViewerPose | Callable[[], ViewerPose],
        follow: str | None = None,
    ) -> None:
        """Move a browser's camera to ``target`` over ``animation_s`` seconds (own thread).

        ``target`` may be a function, read at every step: the viewer flies to a camera that is
        moving. With ``follow`` (a live camera's name) the viewer then stays on that camera as
        it moves (the wrist camera rides the arm) until the next move of this browser's viewer
        (Overview, another camera or snapshot). A new move cancels one still under way.
        """
        goal = target if callable(target) else (lambda: target)
        with self._lock:
            self._generation[client.client_id] = generation = (
                self._generation.get(client.client_id, 0) + 1
            )
            self._following.pop(client.client_id, None)
        start = self.current_viewer(client)

        def current() -> bool:
            return self._generation.get(client.client_id) == generation

        def fly() -> None:
            steps = max(1, int(self.animation_s * 30))
            for k in range(1, steps + 1):
                if not current():
                    return
                self.set_viewer(client, interpolate_viewer(start, goal(), k / steps))
                time.sleep(self.animation_s / steps)
            if not current():
                return
            self.set_viewer(client, goal())
            # the browser reports its camera back as it applies each step; an echo of a step
            # can arrive after the last one, so the target is set once more when it has settled
            time.sleep(0.25)
            with self._lock:
                if not current():
                    return
                if follow is not None:
                    self._following[client.client_id] = follow
            self.set_viewer(client, goal())

        def run() -> None:
            try:
                fly()
            finally:
                with self._lock:
                    if current():
                        self._moving.discard(client.client_id)

        with self._lock:
            self._moving.add(client.client_id)

        threading.Thread(target=run, name="view3d-animate", daemon=True).start()

    def camera_viewer_pose(self, name: str) -> ViewerPose | None:
        """The viewer pose that sees what live camera ``name`` sees now, or None."""
        frustum = self.cameras[name].frustum
        if frustum is None:
            return None
        return viewer_pose_from_camera(frustum.T_world_camera, frustum.fov_y)

    def view_from_camera(self, client: viser.ClientHandle, name: str) -> None:
        """Fly into a live camera's pose and field of view, and stay there as it moves."""
        if self.cameras[name].frustum is None:
            return
        last = [self.camera_viewer_pose(name)]

        def goal() -> ViewerPose:
            pose = self.camera_viewer_pose(name)
            if pose is not None:
                last[0] = pose
            return last[0]

        self.animate_to(client, goal, follow=name)

    def moving(self, client_id: int) -> bool:
        """Whether a browser's viewer is being flown somewhere now."""
        return client_id in self._moving

    def following(self, client_id: int) -> str | None:
        """The live camera a browser's viewer rides with, or None."""
        return self._following.get(client_id)

    def _move_followers(self, name: str) -> None:
        """Keep the viewers that ride with camera ``name`` on its new pose."""
        if name not in self._following.values():
            return
        pose = self.camera_viewer_pose(name)
        clients = self.server.get_clients()
        for client_id, camera in list(self._following.items()):
            if client_id not in clients:
                self._following.pop(client_id, None)  # the browser has gone
            elif camera == name and pose is not None:
                self.set_viewer(clients[client_id], pose)

    def view_from_snapshot(self, client: viser.ClientHandle, snapshot_id: str) -> None:
        if snapshot_id in self.snapshots:
            _, frustum = self.snapshots[snapshot_id]
            self.animate_to(client, viewer_pose_from_camera(frustum.T_world_camera, frustum.fov_y))

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
            node = f"/objects/{_node(name)}"
            T = solid_pose(pose)
            size = np.asarray(size, dtype=float)
            if T is None or not (np.all(np.isfinite(size)) and np.all(size > 0)):
                refused.append(str(name))
                continue
            rgb = tuple(int(c) for c in color)
            if kind == "cylinder":
                self.meshes[node] = cylinder_mesh(node, T, float(size[0]), float(size[2]))
                self.server.scene.add_cylinder(
                    node,
                    radius=float(size[0]),
                    height=float(size[2]),
                    color=rgb,
                    wxyz=wxyz_from_matrix(T[:3, :3]),
                    position=tuple(T[:3, 3]),
                )
            else:
                self.add_box(node, T, size, rgb)
        return refused

    def set_arm(
        self, segments: np.ndarray, joints: np.ndarray, T_world_tool: np.ndarray | None
    ) -> None:
        """Draw the arm's links (``(m, 2, 3)`` segments, m), its joints ``(n, 3)`` and its tool
        frame."""
        colors = np.broadcast_to(np.array([90, 90, 110], dtype=np.uint8), segments.shape)
        self.server.scene.add_line_segments(
            "/arm/links",
            points=segments.astype(np.float32),
            colors=colors,
            thickness=8.0,
            thickness_units="screen",
        )
        self.server.scene.add_point_cloud(
            "/arm/joints",
            points=joints.astype(np.float32),
            colors=(40, 40, 40),
            point_size=0.03,
            point_shape="circle",
        )
        if T_world_tool is not None:
            self.server.scene.add_frame(
                "/arm/tool",
                wxyz=wxyz_from_matrix(T_world_tool[:3, :3]),
                position=tuple(T_world_tool[:3, 3]),
                axes_length=0.06,
                axes_radius=0.004,
            )

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

    # -- snapshots and sketched geometry --------------------------------------------------------

    def add_snapshot(self, snapshot: SceneSnapshot, frustum: Frustum) -> None:
        self.snapshots[snapshot.id] = (snapshot, frustum)
        self.server.scene.add_camera_frustum(
            f"/snapshots/{_node(snapshot.id)}",
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
        self.add_box(f"/sketch/boxes/{_node(box.id)}", box.T_world_box, box.size, (200, 150, 60))

    def add_primitive(self, primitive: ScenePrimitive) -> None:
        name = f"/sketch/primitives/{_node(primitive.id)}"
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


def _node(item_id: str) -> str:
    """A scene-tree name for an item id (no slashes)."""
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in item_id) or "item"
