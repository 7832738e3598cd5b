"""The live 3-D view in a real browser (Debian's Chromium through Playwright): video on the
frustum, the transparency slider, "camera view", and a triad's box surviving reloads."""

from __future__ import annotations

import time
from pathlib import Path

import cv2
import msgspec
import numpy as np
import pytest

from tests.poll import wait_for
from tests.view3d.browser_support import (
    inside_quad,
    needs_chromium,
    project_to_page,
    screenshot,
)
from tests.view3d.view_page import LEFT_MODEL, MAGENTA, T_BASE_CAM_LEFT, View
from umbra.connectors.messages import Image, Pose
from umbra.connectors.sketch_messages import SketchBox
from umbra.modules.calib.rotations import vector_from_rotation
from umbra.modules.geometry.transforms import transform_from_xyz_rpy_deg
from umbra.modules.view3d.geometry import (
    frustum_from_model,
    matrix_from_wxyz,
    viewer_pose_from_camera,
    viewer_pose_looking_at,
)
from umbra.modules.view3d.viewer_video import FRUSTUM_SCALES

pytestmark = [pytest.mark.browser, needs_chromium]


@pytest.fixture(scope="module")
def view(browser, tmp_path_factory):
    v = View(
        browser, {"port": 0, "animation_s": 0.3, "max_fps": 20}, tmp_path_factory.mktemp("view3d")
    )
    image = np.zeros((480, 640, 3), np.uint8)
    image[:] = MAGENTA[::-1]  # BGR
    v.feed("left_model", LEFT_MODEL)
    v.feed("left_image", Image(pixels=image))
    wait_for(
        lambda: v.module.page.cameras["left"].frames_sent > 0,
        20.0,
        "a video frame sent",
        interval_s=0.05,
    )
    yield v
    v.close()


def _image_quad(view: View, client) -> np.ndarray:
    frustum = frustum_from_model(LEFT_MODEL, T_BASE_CAM_LEFT)
    corners = frustum.image_plane_corners(frustum.image_depth(FRUSTUM_SCALES["left"]))
    return project_to_page(client, view.canvas, corners)


def _behind_camera(view: View) -> None:
    """Put the viewer 0.35 m behind the left camera, looking where it looks."""
    T = T_BASE_CAM_LEFT.copy()
    T[:3, 3] -= 0.35 * T[:3, 2]
    pose = viewer_pose_from_camera(T, 1.0)
    view.move_viewer(pose, "the viewer camera to move")


def _fraction_near(pixels: np.ndarray, color: np.ndarray, tolerance: float) -> float:
    return float(np.mean(np.linalg.norm(pixels.astype(float) - color, axis=1) < tolerance))


def test_video_pixels_inside_the_frustum_projection(view: View) -> None:
    _behind_camera(view)
    quad = _image_quad(view, view.client)
    shot_shape = (
        int(view.canvas.top + view.canvas.height),
        int(view.canvas.left + view.canvas.width),
    )

    def video_in_place():
        shot = screenshot(view.page)[: shot_shape[0], : shot_shape[1]]
        inner = shot[inside_quad(quad, shot.shape[:2], 6.0)]
        ring = shot[
            inside_quad(quad, shot.shape[:2], -12.0) & ~inside_quad(quad, shot.shape[:2], -4.0)
        ]
        return (
            _fraction_near(inner, MAGENTA, 30) > 0.97 and _fraction_near(ring, MAGENTA, 60) < 0.05,
            inner.shape[0],
        )

    _, count = wait_for(
        video_in_place, 20.0, "video in the frustum", interval_s=0.05, ok=lambda r: r[0]
    )
    assert count > 5000  # the image covers a real area of the page


def test_zoom_narrows_the_frustum_and_its_video(view: View) -> None:
    """A zoomed camera model (longer focal length) narrows the frustum in the page: the video
    fills the new, smaller projection and nothing of it is left outside."""
    _behind_camera(view)
    wide = _image_quad(view, view.client)
    zoomed = msgspec.structs.replace(LEFT_MODEL, fx=1200.0, fy=1200.0)
    narrow_frustum = frustum_from_model(zoomed, T_BASE_CAM_LEFT)
    corners = narrow_frustum.image_plane_corners(narrow_frustum.image_depth(FRUSTUM_SCALES["left"]))
    try:
        view.feed("left_model", zoomed)
        wait_for(
            lambda: (
                abs(view.module.page.cameras["left"].frustum.fov_y - narrow_frustum.fov_y) < 1e-12
            ),
            20.0,
            "the zoomed frustum",
            interval_s=0.05,
        )

        def video_in_narrow() -> bool:
            _behind_camera(view)
            narrow = project_to_page(view.client, view.canvas, corners)
            shot = screenshot(view.page)
            inner = shot[inside_quad(narrow, shot.shape[:2], 6.0)]
            ring = shot[
                inside_quad(narrow, shot.shape[:2], -12.0)
                & ~inside_quad(narrow, shot.shape[:2], -4.0)
            ]
            area = cv2.contourArea(narrow.astype(np.float32))
            return (
                area < 0.5 * cv2.contourArea(wide.astype(np.float32))
                # the frustum's edges, seen end on, cross the smaller image: 5 % of it
                and _fraction_near(inner, MAGENTA, 30) > 0.9
                and _fraction_near(ring, MAGENTA, 60) < 0.05
            )

        wait_for(video_in_narrow, 20.0, "the video in the narrowed frustum", interval_s=0.05)
    finally:
        view.feed("left_model", LEFT_MODEL)
        wide_fov = frustum_from_model(LEFT_MODEL, T_BASE_CAM_LEFT).fov_y
        wait_for(
            lambda: abs(view.module.page.cameras["left"].frustum.fov_y - wide_fov) < 1e-12,
            20.0,
            "the frustum back to its width",
            interval_s=0.05,
        )


def test_transparency_slider_blends_the_video_with_the_model(view: View) -> None:
    """The slider (driven by keys in the page) sets the video's alpha: the page shows the
    model through it, blended pixel by pixel (the green channel: magenta has none)."""
    _behind_camera(view)
    quad = _image_quad(view, view.client)
    sliders = view.page.locator('[role="slider"]')
    assert sliders.count() == 1  # only the camera the graph feeds (left) is offered
    slider = sliders.nth(0)
    slider.focus()

    def inner() -> np.ndarray:
        shot = screenshot(view.page)
        return shot[inside_quad(quad, shot.shape[:2], 10.0)].astype(float)

    slider.press("Home")  # opacity 0: only the model behind the image
    wait_for(
        lambda: view.module.page.cameras["left"].opacity == 0.0, 20.0, "opacity 0", interval_s=0.05
    )
    _behind_camera(view)  # arrow keys also steer viser's camera: put it back
    behind = wait_for(
        inner,
        20.0,
        "a transparent video",
        interval_s=0.05,
        ok=lambda px: _fraction_near(px, MAGENTA, 100) < 0.01,
    )
    for _ in range(6):  # 6 steps of 0.05: opacity 0.3
        slider.press("ArrowRight")
    wait_for(
        lambda: abs(view.module.page.cameras["left"].opacity - 0.3) < 1e-9,
        20.0,
        "0.3",
        interval_s=0.05,
    )
    _behind_camera(view)
    usable = behind[:, 1] > 100

    def alpha(px: np.ndarray) -> float:
        return float(np.median(1.0 - px[usable, 1] / behind[usable, 1]))

    assert usable.mean() > 0.5
    seen = wait_for(
        lambda: alpha(inner()),
        20.0,
        "alpha 0.3 in the page",
        interval_s=0.05,
        ok=lambda a: abs(a - 0.3) < 0.05,
    )
    assert abs(seen - 0.3) < 0.05
    slider.press("End")
    _behind_camera(view)
    wait_for(
        inner,
        20.0,
        "the opaque video again",
        interval_s=0.05,
        ok=lambda px: _fraction_near(px, MAGENTA, 30) > 0.95,
    )


def _viewer_error(client, T_world_camera: np.ndarray, fov_y: float) -> tuple[float, float, float]:
    """The viewer against a camera pose, as the browser last reported its camera: metres,
    degrees, and the field of view's difference (rad)."""
    cam = client.camera
    R = matrix_from_wxyz(cam.wxyz)
    angle = np.degrees(np.linalg.norm(vector_from_rotation(R.T @ T_world_camera[:3, :3])))
    offset = float(np.linalg.norm(np.asarray(cam.position) - T_world_camera[:3, 3]))
    return offset, float(angle), abs(cam.fov - fov_y)


def _within(e: tuple[float, float, float]) -> bool:
    return e[0] < 1e-3 and e[1] < 0.1 and e[2] < 1e-6


def test_camera_view_button_puts_the_viewer_at_the_camera(view: View) -> None:
    view.move_viewer(view.module.page.overview, "the overview")
    view.page.get_by_role("button", name="View from left").click()
    frustum = frustum_from_model(LEFT_MODEL, T_BASE_CAM_LEFT)

    def error() -> tuple[float, float, float]:
        return _viewer_error(view.client, T_BASE_CAM_LEFT, frustum.fov_y)

    # the browser reports its camera as it moves; once there, it stays there
    wait_for(error, 20.0, "the viewer at the camera (1 mm, 0.1 deg)", interval_s=0.05, ok=_within)
    time.sleep(0.5)
    final = error()
    assert _within(final), final
    # and back to the overview, animated: the browser reports poses in between (every report
    # is kept: a loaded machine may starve this thread for longer than the flight)
    overview = view.module.page.overview
    start = np.asarray(view.client.camera.position).copy()
    total = np.linalg.norm(overview.position - start)
    reported: list[np.ndarray] = []
    view.client.camera.on_update(lambda camera: reported.append(np.array(camera.position)))
    view.page.get_by_role("button", name="Overview").click()
    wait_for(
        lambda: np.linalg.norm(view.client.camera.position - overview.position) < 1e-3,
        20.0,
        "the overview",
        interval_s=0.05,
    )
    between = [p for p in reported if 0.05 < np.linalg.norm(p - start) < total - 0.05]
    assert between, f"no pose between the camera and the overview among {len(reported)}"


def test_camera_view_rides_with_a_moving_camera_until_overview(view: View) -> None:
    """A wrist camera moves with the arm: "View from" keeps the viewer on the camera as it
    moves (and a move during the flight changes where the flight ends); "Overview" lets go."""
    frustum = frustum_from_model(LEFT_MODEL, T_BASE_CAM_LEFT)
    moved = [
        T_BASE_CAM_LEFT @ transform_from_xyz_rpy_deg([0.05 * k, -0.03 * k, 0.02], [2 * k, 0, -k])
        for k in (1, 2, 3)
    ]
    try:
        view.page.get_by_role("button", name="View from left").click()
        view.feed("left_pose", Pose(matrix=moved[0], parent="base", child="left"))
        wait_for(
            lambda: _viewer_error(view.client, moved[0], frustum.fov_y),
            20.0,
            "the viewer at the camera's pose of during the flight",
            interval_s=0.05,
            ok=_within,
        )
        wait_for(
            lambda: view.module.page.following(view.client.client_id) == "left",
            20.0,
            "the flight's end",
            interval_s=0.05,
        )
        view.feed("left_pose", Pose(matrix=moved[1], parent="base", child="left"))
        wait_for(
            lambda: _viewer_error(view.client, moved[1], frustum.fov_y),
            20.0,
            "the viewer riding with the moved camera (1 mm, 0.1 deg)",
            interval_s=0.05,
            ok=_within,
        )
        view.page.get_by_role("button", name="Overview").click()
        overview = view.module.page.overview
        wait_for(
            lambda: np.linalg.norm(view.client.camera.position - overview.position) < 1e-3,
            20.0,
            "the overview",
            interval_s=0.05,
        )
        view.feed("left_pose", Pose(matrix=moved[2], parent="base", child="left"))
        wait_for(
            lambda: (
                view.module.page.cameras["left"].frustum is not None
                and np.allclose(view.module.page.cameras["left"].frustum.T_world_camera, moved[2])
            ),
            20.0,
            "the camera moved on the page",
            interval_s=0.05,
        )
        time.sleep(0.5)  # a window: the viewer does not follow the camera
        assert np.linalg.norm(view.client.camera.position - overview.position) < 1e-3
        assert view.module.page.following(view.client.client_id) is None
    finally:
        view.feed("left_pose", Pose(matrix=T_BASE_CAM_LEFT, parent="base", child="left"))
        wait_for(
            lambda: np.allclose(
                view.module.page.cameras["left"].frustum.T_world_camera, T_BASE_CAM_LEFT
            ),
            20.0,
            "the camera back in place",
            interval_s=0.05,
        )


@pytest.mark.slow
def test_triad_box_appears_and_survives_page_and_scene_reload(
    view: View, browser, tmp_path
) -> None:
    T_box = transform_from_xyz_rpy_deg([0.5, 0.25, 0.33], [0, 0, 30])
    view.feed("box", SketchBox(box_id="box-1", T_base_box=T_box, size=np.array([0.2, 0.12, 0.16])))
    top = T_box[:3, 3] + np.array([0, 0, 0.08])
    pose = viewer_pose_looking_at([0.5, -0.45, 1.3], top, 0.9)

    def box_seen(v: View) -> bool:
        v.move_viewer(pose, "viewer")
        u, w = project_to_page(v.client, v.canvas, top[None])[0].round().astype(int)
        patch = screenshot(v.page)[w - 4 : w + 5, u - 4 : u + 5].reshape(-1, 3).astype(int)
        # the box's (lit) ochre, unlike the grey-white table and background
        ochre = (patch[:, 0] - patch[:, 2] > 50) & (patch[:, 0] >= patch[:, 1])
        ochre &= patch[:, 1] >= patch[:, 2]
        return bool(ochre.mean() > 0.8)

    wait_for(lambda: box_seen(view), 20.0, "the box in the page", interval_s=0.05)
    scene_path = Path(view.module.summary()["scene_file"])
    wait_for(
        lambda: scene_path.exists() and "box-1" in scene_path.read_text(),
        20.0,
        "saved",
        interval_s=0.05,
    )
    view.page.reload()
    view.client = wait_for(view._client, 20.0, "the reloaded page to connect", interval_s=0.05)
    view.settle_layout()
    wait_for(lambda: box_seen(view), 20.0, "the box after a page reload", interval_s=0.05)
    # a new view (a new run) loading the scene file shows the box too
    again = View(browser, {"port": 0, "load_scene": str(scene_path)}, tmp_path)
    try:
        wait_for(
            lambda: box_seen(again), 20.0, "the box from the reloaded scene file", interval_s=0.05
        )
        saved_again = Path(again.module.summary()["scene_file"])
        wait_for(
            lambda: saved_again.exists() and "box-1" in saved_again.read_text(),
            20.0,
            "the loaded scene saved in the new run's folder",
            interval_s=0.05,
        )
    finally:
        again.close()
