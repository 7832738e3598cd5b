"""Geometry of the 3-D view, without a browser: frusta, arm links, rays, the viewer's camera."""

from __future__ import annotations

import numpy as np
import pytest

from umbra.connectors.messages import CameraModel
from umbra.modules.arm.dh import puma560
from umbra.modules.calib.camera_model import Intrinsics, PinholeCamera
from umbra.modules.geometry.transforms import transform_from_xyz_rpy_deg, transform_points
from umbra.modules.view3d.geometry import (
    arm_joint_points,
    arm_link_segments,
    box_mesh,
    frustum_from_model,
    interpolate_viewer,
    matrix_from_wxyz,
    pixel_of_ray_on_image,
    quad_mesh,
    ray_hit,
    viewer_pose_from_camera,
    viewer_pose_looking_at,
    wxyz_from_matrix,
)
from umbra.modules.view3d.viewer_video import video_rgba

T_WORLD_MOUNT = transform_from_xyz_rpy_deg([0.6, -0.3, 1.5], [180.0, -5.0, 10.0])
T_MOUNT_CAMERA = transform_from_xyz_rpy_deg([0.01, 0.02, 0.03], [1.0, -2.0, 3.0])


def model(fx: float = 800.0, fy: float = 790.0) -> CameraModel:
    return CameraModel(
        fx=fx, fy=fy, u0=320.0, v0=240.0, width=640, height=480, T_mount_camera=T_MOUNT_CAMERA
    )


def test_frustum_pose_and_field_of_view_from_camera_model() -> None:
    f = frustum_from_model(model(), T_WORLD_MOUNT)
    np.testing.assert_allclose(f.T_world_camera, T_WORLD_MOUNT @ T_MOUNT_CAMERA, atol=1e-12)
    assert f.fov_y == pytest.approx(2 * np.arctan(240.0 / 790.0))
    assert f.aspect == pytest.approx((640 / 800) / (480 / 790))
    # zooming in (focal length doubled) narrows the frustum
    zoomed = frustum_from_model(model(1600.0, 1580.0), T_WORLD_MOUNT)
    assert np.tan(zoomed.fov_y / 2) == pytest.approx(np.tan(f.fov_y / 2) / 2)
    with pytest.raises(ValueError, match="positive"):
        frustum_from_model(
            CameraModel(fx=0.0, fy=1.0, u0=0.0, v0=0.0, width=640, height=480), T_WORLD_MOUNT
        )


def test_image_plane_corners_project_to_the_image_corners() -> None:
    f = frustum_from_model(model(), T_WORLD_MOUNT)
    camera = PinholeCamera(Intrinsics(800.0, 790.0, 0.0, 320.0, 240.0))
    camera = camera.with_extrinsic_matrix(np.linalg.inv(f.T_world_camera))
    depth = f.image_depth(0.15)
    corners = f.image_plane_corners(depth)
    np.testing.assert_allclose(
        camera.project(corners), [[0, 0], [640, 0], [640, 480], [0, 480]], atol=1e-9
    )
    np.testing.assert_allclose(camera.to_camera_frame(corners)[:, 2], depth, atol=1e-12)
    # viser's drawing rule: half height of the image plane = tan(fov/2) * depth, and the
    # pyramid (tan(fov/2) aspect, tan(fov/2), 1) scaled to volume 3 * scale^3
    y = np.tan(f.fov_y / 2)
    assert (y * depth) * (y * f.aspect * depth) * depth == pytest.approx(3 * 0.15**3)


def test_click_on_the_image_plane_gives_the_pixel() -> None:
    f = frustum_from_model(model(), T_WORLD_MOUNT)
    depth = f.image_depth(0.2)
    target = np.array([123.0, 401.5])
    on_plane = f.points_from_pixels(target[None], depth)[0]
    origin = np.array([2.0, 1.0, 3.0])
    uv = pixel_of_ray_on_image(origin, on_plane - origin, f, depth)
    np.testing.assert_allclose(uv, target, atol=1e-9)
    assert pixel_of_ray_on_image(origin, origin - on_plane, f, depth) is None  # points away
    outside = f.points_from_pixels([[700.0, 10.0]], depth)[0]
    assert pixel_of_ray_on_image(origin, outside - origin, f, depth) is None
    np.testing.assert_allclose(f.pixel_of(on_plane), target, atol=1e-9)


def test_dh_link_points_follow_forward_kinematics() -> None:
    table = puma560()
    q = np.radians([14.482, 45.603, -182.743, 0.0, -42.86, -165.518])
    T_world_base = transform_from_xyz_rpy_deg([0.1, 0.2, 0.0], [0, 0, 30])
    T_flange_tool = transform_from_xyz_rpy_deg([0, 0, 0.14], [0, 0, 0])
    points = arm_joint_points(table, q, T_world_base, T_flange_tool)
    assert points.shape == (table.n + 2, 3)
    np.testing.assert_allclose(points[0], [0.1, 0.2, 0.0], atol=1e-12)
    np.testing.assert_allclose(points[-2], (T_world_base @ table.fk(q))[:3, 3], atol=1e-12)
    np.testing.assert_allclose(
        points[-1], (T_world_base @ table.fk(q, T_flange_tool))[:3, 3], atol=1e-12
    )
    frames = table.frames(q)
    for i in range(table.n + 1):
        np.testing.assert_allclose(points[i], transform_points(T_world_base, frames[i][:3, 3]))
    segments = arm_link_segments(points)
    lengths = np.linalg.norm(segments[:, 1] - segments[:, 0], axis=1)
    assert np.all(lengths > 1e-6)
    # the Puma's upper arm a2 = 0.4318 m is one of the drawn links
    assert np.any(np.isclose(lengths, 0.4318, atol=1e-4))


def test_ray_hits_the_nearest_surface_point() -> None:
    table_top = transform_from_xyz_rpy_deg([0.5, 0.0, 0.23], [0, 0, 0])
    box = transform_from_xyz_rpy_deg([0.6, 0.1, 0.30], [0, 0, 35])
    meshes = [box_mesh("table", table_top, [1.4, 1.2, 0.04]), box_mesh("box", box, [0.1, 0.1, 0.1])]
    down = np.array([0.0, 0.0, -1.0])
    hit = ray_hit([0.6, 0.1, 2.0], down, meshes)
    assert hit is not None and hit.name == "box"
    np.testing.assert_allclose(hit.point, [0.6, 0.1, 0.35], atol=1e-12)
    assert hit.distance == pytest.approx(1.65)
    hit = ray_hit([0.0, -0.4, 2.0], down, meshes)
    assert hit is not None and hit.name == "table"
    np.testing.assert_allclose(hit.point, [0.0, -0.4, 0.25], atol=1e-12)
    # an oblique ray onto the box's rotated side face
    origin = np.array([1.5, 0.1, 0.3])
    hit = ray_hit(origin, [-1.0, 0.0, 0.0], meshes)
    assert hit is not None and hit.name == "box"
    local = np.linalg.inv(box) @ np.append(hit.point, 1.0)
    assert np.isclose(np.max(np.abs(local[:2])), 0.05)  # on a side face of the box
    assert ray_hit([0.0, 0.0, 2.0], [0.0, 0.0, 1.0], meshes) is None  # away from everything
    quad = quad_mesh("q", [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    hit = ray_hit([0.25, 0.75, 1.0], [0.0, 0.0, -1.0], [quad])
    np.testing.assert_allclose(hit.point, [0.25, 0.75, 0.0], atol=1e-12)
    with pytest.raises(ValueError, match="direction"):
        ray_hit([0, 0, 0], [0, 0, 0], meshes)


def test_viewer_pose_equals_the_camera_pose() -> None:
    T = T_WORLD_MOUNT @ T_MOUNT_CAMERA
    pose = viewer_pose_from_camera(T, 0.7)
    np.testing.assert_allclose(matrix_from_wxyz(pose.wxyz), T[:3, :3], atol=1e-12)
    np.testing.assert_allclose(pose.position, T[:3, 3])
    np.testing.assert_allclose(pose.look_at - pose.position, T[:3, 2])
    np.testing.assert_allclose(pose.up, -T[:3, 1])
    np.testing.assert_allclose(wxyz_from_matrix(matrix_from_wxyz(pose.wxyz)), pose.wxyz)


def test_viewer_animation_starts_and_ends_at_rest_on_the_poses() -> None:
    a = viewer_pose_looking_at([2.0, -1.0, 1.5], [0.5, 0.0, 0.3], 0.9)
    b = viewer_pose_from_camera(T_WORLD_MOUNT, 0.4)
    start, end = interpolate_viewer(a, b, 0.0), interpolate_viewer(a, b, 1.0)
    np.testing.assert_allclose(start.position, a.position)
    np.testing.assert_allclose(end.position, b.position)
    np.testing.assert_allclose(matrix_from_wxyz(end.wxyz), matrix_from_wxyz(b.wxyz), atol=1e-12)
    assert end.fov_y == pytest.approx(0.4)
    # eased: the first step is much smaller than the middle one
    early = np.linalg.norm(interpolate_viewer(a, b, 0.05).position - a.position)
    middle = np.linalg.norm(
        interpolate_viewer(a, b, 0.55).position - interpolate_viewer(a, b, 0.5).position
    )
    assert early < 0.2 * middle
    # looking from the overview's camera: the target is straight ahead
    R = matrix_from_wxyz(a.wxyz)
    direction = np.array([0.5, 0.0, 0.3]) - a.position
    np.testing.assert_allclose(R[:, 2], direction / np.linalg.norm(direction), atol=1e-12)
    assert R[:, 1] @ np.array([0, 0, 1.0]) < 0  # image down is world down


def test_video_rgba_alpha_follows_the_opacity() -> None:
    image = np.zeros((480, 640, 3), np.uint8)
    image[..., 2] = 200  # red in BGR
    opaque = video_rgba(image, 1.0, 320)
    assert opaque.shape == (240, 320, 3) and opaque[0, 0].tolist() == [200, 0, 0]
    half = video_rgba(image, 0.4, 320)
    assert half.shape == (240, 320, 4) and half[5, 5].tolist() == [200, 0, 0, 102]
    assert video_rgba(image, 0.0, 1000)[..., 3].max() == 0


def test_ray_hits_a_cylinder_on_its_side_and_its_cap() -> None:
    from umbra.modules.view3d.geometry import cylinder_mesh

    T = transform_from_xyz_rpy_deg([0.5, 0.0, 0.3], [90, 0, 0])  # axis along world -y
    pipe = cylinder_mesh("pipe", T, 0.04, 0.6, segments=64)
    hit = ray_hit([0.5, 0.1, 1.0], [0, 0, -1.0], [pipe])
    assert hit is not None and hit.point[2] == pytest.approx(0.34, abs=2e-4)  # top of the pipe
    hit = ray_hit([0.5, -2.0, 0.3], [0, 1.0, 0], [pipe])
    assert hit is not None and hit.point[1] == pytest.approx(-0.3)  # the end cap
