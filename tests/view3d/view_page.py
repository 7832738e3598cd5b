"""A View3D module in a harness with one Chromium page on it, and the scene the 3-D view's
browser tests show: the frames of a small workcell and the left PTU camera looking at it."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from tests.poll import wait_for
from tests.view3d.browser_support import block_outside_loopback, canvas_box
from umbra.connectors.messages import CameraModel
from umbra.modules.geometry.transforms import transform_from_xyz_rpy_deg
from umbra.modules.view3d.geometry import matrix_from_wxyz, viewer_pose_looking_at
from umbra.modules.view3d.view3d import View3D
from umbra.runtime.harness import ModuleHarness

_RESEND_S = 2.0  # [s] a pose the browser has not reported is sent again after this
MAGENTA = np.array([255, 0, 255])  # the left camera's video, RGB
T_BASE_CAM_LEFT = np.eye(4)
_look = viewer_pose_looking_at([0.6, -0.9, 1.1], [0.6, 0.0, 0.25], 0.8)
T_BASE_CAM_LEFT[:3, :3] = matrix_from_wxyz(_look.wxyz)
T_BASE_CAM_LEFT[:3, 3] = _look.position
FRAMES = {
    "base->table": transform_from_xyz_rpy_deg([0, 0, 0.25], [0, 0, 0]),
    "flange->tool": transform_from_xyz_rpy_deg([0, 0, 0.14], [0, 0, 0]),
    "tool->camera": transform_from_xyz_rpy_deg([0, 0, -0.12], [0, 0, 0]),
    "base->cam_left": T_BASE_CAM_LEFT,
}
LEFT_MODEL = CameraModel(
    fx=600.0, fy=600.0, u0=320.0, v0=240.0, width=640, height=480, mount="cam_left", frame="left"
)


def first_client(module: View3D):
    """The first browser on ``module``'s page once it has reported its camera (None before)."""
    clients = list(module.page.server.get_clients().values())
    if not clients:
        return None
    try:
        clients[0].camera.position  # noqa: B018  (raises until the browser reported it)
    except AssertionError:
        return None
    return clients[0]


class View:
    """A View3D module in a harness and one Chromium page showing it."""

    def __init__(self, browser, params: dict, output_dir: Path) -> None:
        self.harness = ModuleHarness(View3D, params, frames=FRAMES, output_dir=output_dir)
        self.harness.__enter__()
        self.module = self.harness.module
        self.page = browser.new_page(viewport={"width": 1100, "height": 700})
        block_outside_loopback(self.page)
        self.page.goto(self.module.address)
        self.client = wait_for(
            self._client, 20.0, "the browser to connect to viser", interval_s=0.05
        )
        self.settle_layout()

    def settle_layout(self) -> None:
        """Wait until the control panel is docked beside the canvas (the canvas narrows)."""
        self.canvas = wait_for(
            lambda: canvas_box(self.page),
            20.0,
            "the docked panel",
            interval_s=0.05,
            ok=lambda c: c is not None and 0 < c.width < 1000,
        )

    def _client(self):
        return first_client(self.module)

    def move_viewer(self, pose, what: str, tolerance_m: float = 1e-4) -> None:
        """Put the page's viewer at ``pose`` and wait until the browser reports it there.

        Between looks the pose is sent again (``wait_for``'s ``step``) in two cases seen on
        loaded machines:
        - the page's socket closed and viser's page reconnected as a new client (the pose had
          queued on the closed connection): it goes to whichever client the page is now, and
          ``self.client`` follows it;
        - the browser never reported it after arrow keys had been pressed on a slider (they
          also steer viser's camera): it is sent again every ``_RESEND_S`` [s].
        """
        sent_to: list[object] = [None]
        sent_at = [0.0]

        def send() -> None:
            client = self._client()
            if client is None:
                return
            if client is not sent_to[0] or time.monotonic() - sent_at[0] > _RESEND_S:
                self.client = client
                self.module.page.set_viewer(client, pose)
                sent_to[0] = client
                sent_at[0] = time.monotonic()

        def there() -> bool:
            client = self._client()
            return client is not None and bool(
                np.linalg.norm(client.camera.position - pose.position) < tolerance_m
                and np.linalg.norm(client.camera.look_at - pose.look_at) < tolerance_m
            )

        send()
        wait_for(there, 20.0, what, interval_s=0.05, step=send)

    def feed(self, port: str, sample) -> None:
        self.harness.push(port, sample)
        self.harness.step(dt=0.05)

    def close(self) -> None:
        self.page.close()
        self.harness.__exit__(None, None, None)
