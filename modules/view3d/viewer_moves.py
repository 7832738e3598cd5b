"""Where each browser's viewer looks: set it, fly it to a pose, into a live camera's view (and
ride along as that camera moves), into a snapshot's (a mixin of
:class:`~umbra.modules.view3d.viewer.ViewerPage`, which holds the server and the cameras)."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np
import viser

from umbra.modules.view3d.geometry import ViewerPose, interpolate_viewer, viewer_pose_from_camera


class ViewerMoves:
    """The viewer's camera, per browser."""

    server: Any
    cameras: dict[str, Any]
    snapshots: dict[str, Any]
    animation_s: float
    _lock: threading.Lock
    _generation: dict[int, int]
    _following: dict[int, str]
    _moving: set[int]

    def set_viewer(self, client: viser.ClientHandle, pose: ViewerPose) -> None:
        """Put one browser's camera at ``pose`` at once."""
        with client.atomic():
            client.camera.fov = pose.fov_y
            client.camera.position = pose.position
            client.camera.look_at = pose.look_at
            client.camera.up_direction = pose.up

    def current_viewer(self, client: viser.ClientHandle) -> ViewerPose:
        cam = client.camera
        from umbra.modules.view3d.geometry import matrix_from_wxyz

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

        def latest() -> bool:
            """This move is still the browser's latest."""
            return self._generation.get(client.client_id) == generation

        def current() -> bool:
            """... and the browser is still there (one that left mid-move is sent nothing)."""
            return latest() and client.client_id in self.server.get_clients()

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
                    if latest():
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
        start = self.camera_viewer_pose(name)
        if start is None:  # the camera has no frustum yet
            return
        last = [start]

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
