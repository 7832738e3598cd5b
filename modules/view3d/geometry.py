"""Geometry of the 3-D view: camera frusta, the viewer's camera, arm links, rays hitting surfaces.

Frames: ``world`` is the view's reference frame (the graph's ``base`` by default, z up). Camera
frames follow OpenCV (x right, y down, z along the optic axis), as do viser's cameras, so a
camera pose ``T_world_camera`` is used as it is for a frustum and for the viewer. Quaternions are
``(w, x, y, z)``. Units: metres and radians.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation, Slerp

from umbra.connectors.messages import CameraModel
from umbra.modules.arm.dh import DHTable
from umbra.modules.geometry.transforms import is_orthonormal_transform

FloatArray = NDArray[np.float64]


def wxyz_from_matrix(R: ArrayLike) -> FloatArray:
    """Unit quaternion ``(w, x, y, z)`` of a rotation matrix (``w >= 0``)."""
    x, y, z, w = Rotation.from_matrix(np.asarray(R, dtype=float)).as_quat()
    q = np.array([w, x, y, z])
    return q if w >= 0 else -q


def matrix_from_wxyz(wxyz: ArrayLike) -> FloatArray:
    """Rotation matrix of a quaternion ``(w, x, y, z)``."""
    w, x, y, z = np.asarray(wxyz, dtype=float)
    return Rotation.from_quat([x, y, z, w]).as_matrix()


@dataclass(frozen=True, eq=False)
class Frustum:
    """A camera's viewing pyramid: pose ``T_world_camera`` (4x4, m), vertical field of view
    ``fov_y`` (rad), ``aspect`` (tan of the half-width over tan of the half-height), image size
    (px) and intrinsics ``K`` (3x3, px)."""

    T_world_camera: FloatArray
    fov_y: float
    aspect: float
    width: int
    height: int
    K: FloatArray

    @property
    def drawn_K(self) -> FloatArray:
        """The intrinsics the 3-D view draws with: the focal lengths, the principal point at the
        image centre (viser's frustum is a symmetric pyramid; skew is not drawn)."""
        return np.array(
            [
                [self.K[0, 0], 0.0, self.width / 2.0],
                [0.0, self.K[1, 1], self.height / 2.0],
                [0.0, 0.0, 1.0],
            ]
        )

    def image_depth(self, scale: float) -> float:
        """Depth (m, camera z) at which viser draws the image of a frustum of size ``scale``:
        it normalizes the pyramid ``(tan(fov/2) aspect, tan(fov/2), 1)`` to volume 3 and
        multiplies by ``scale``."""
        y = np.tan(self.fov_y / 2.0)
        return float(scale / np.cbrt(y * y * self.aspect / 3.0))

    def image_plane_corners(self, depth: float) -> FloatArray:
        """World coordinates ``(4, 3)`` of the image corners (top-left, top-right, bottom-right,
        bottom-left, pixel edges) on the plane ``z = depth`` of the camera."""
        uv = np.array(
            [[0.0, 0.0], [self.width, 0.0], [self.width, self.height], [0.0, self.height]]
        )
        return self.points_from_pixels(uv, depth)

    def points_from_pixels(self, pixels: ArrayLike, depth: float) -> FloatArray:
        """World points ``(n, 3)`` of pixels ``(n, 2)`` on the drawn image at camera depth."""
        uv = np.asarray(pixels, dtype=float).reshape(-1, 2)
        rays = np.linalg.solve(self.drawn_K, np.hstack([uv, np.ones((len(uv), 1))]).T).T
        camera_points = rays * depth
        return camera_points @ self.T_world_camera[:3, :3].T + self.T_world_camera[:3, 3]

    def pixel_of(self, point_world: ArrayLike) -> FloatArray:
        """Ideal pixel ``(2,)`` of a world point (nan when behind the camera)."""
        p = np.asarray(point_world, dtype=float) - self.T_world_camera[:3, 3]
        c = self.T_world_camera[:3, :3].T @ p
        if c[2] <= 0:
            return np.full(2, np.nan)
        h = self.K @ (c / c[2])
        return h[:2]


def solid_pose(T: ArrayLike, tolerance: float = 1e-6) -> FloatArray | None:
    """A box's or cylinder's pose (4x4) as a rigid transform, or None when it is not one.

    Both solids are symmetric about their centre planes, so a pose whose axes are a
    reflection (orthonormal, determinant -1) describes the same solid as the rigid pose with
    its z axis turned round; that pose is returned. Anything else (scaled, sheared,
    non-finite) is None: the solid cannot be drawn."""
    if not is_orthonormal_transform(T, tolerance):
        return None
    M = np.asarray(T, dtype=float)
    R = M[:3, :3]
    if np.linalg.det(R) > 0:
        return M.copy()
    rigid = M.copy()
    rigid[:3, 2] = -R[:, 2]
    return rigid


def frustum_from_model(model: CameraModel, T_world_mount: ArrayLike) -> Frustum:
    """The frustum of a camera model whose mount is at ``T_world_mount``.

    The pose is ``T_world_mount . T_mount_camera``; the field of view follows the focal length,
    so zooming narrows the frustum. The principal point is taken as given in ``K`` (the image
    is drawn at the pixels' true rays by :meth:`Frustum.image_plane_corners`); the frustum's
    symmetric pyramid uses the focal lengths only.
    """
    T_world_camera = np.asarray(T_world_mount, dtype=float) @ np.asarray(
        model.T_mount_camera, dtype=float
    )
    width, height = int(model.width), int(model.height)
    if width <= 0 or height <= 0 or not (model.fx > 0 and model.fy > 0):
        raise ValueError(
            f"camera model {model.frame!r} needs a positive size and focal lengths, got "
            f"{width}x{height} px, fx {model.fx}, fy {model.fy}"
        )
    fov_y = 2.0 * float(np.arctan2(height / 2.0, model.fy))
    aspect = (width / model.fx) / (height / model.fy)
    return Frustum(T_world_camera, fov_y, aspect, width, height, np.asarray(model.K, dtype=float))


@dataclass(frozen=True)
class ViewerPose:
    """Where to put the viewer's camera: position (m), orientation ``(w, x, y, z)`` of the
    OpenCV camera frame in the world, vertical field of view (rad), a look-at point (m) and
    the up direction (world)."""

    position: FloatArray
    wxyz: FloatArray
    fov_y: float
    look_at: FloatArray
    up: FloatArray


def viewer_pose_from_camera(
    T_world_camera: ArrayLike, fov_y: float, look_distance: float = 1.0
) -> ViewerPose:
    """The viewer pose that sees what a camera sees (Figure 16's video perspective)."""
    T = np.asarray(T_world_camera, dtype=float)
    R = T[:3, :3]
    position = T[:3, 3].copy()
    return ViewerPose(
        position=position,
        wxyz=wxyz_from_matrix(R),
        fov_y=float(fov_y),
        look_at=position + look_distance * R[:, 2],
        up=-R[:, 1],
    )


def viewer_pose_looking_at(
    position: ArrayLike, target: ArrayLike, fov_y: float, up: ArrayLike = (0.0, 0.0, 1.0)
) -> ViewerPose:
    """A viewer at ``position`` looking at ``target`` with ``up`` up (an overview)."""
    p = np.asarray(position, dtype=float)
    t = np.asarray(target, dtype=float)
    z = t - p
    z /= np.linalg.norm(z)
    x = np.cross(z, np.asarray(up, dtype=float))
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.stack([x, y, z], axis=1)
    return ViewerPose(p, wxyz_from_matrix(R), float(fov_y), t, -y)


def interpolate_viewer(a: ViewerPose, b: ViewerPose, s: float) -> ViewerPose:
    """The viewer pose a fraction ``s`` (0..1, eased) of the way from ``a`` to ``b``:
    position, look-at point and field of view linearly, orientation by slerp."""
    s = float(np.clip(s, 0.0, 1.0))
    e = s * s * (3.0 - 2.0 * s)  # smoothstep: starts and ends at rest
    rotations = Rotation.from_quat(
        [[a.wxyz[1], a.wxyz[2], a.wxyz[3], a.wxyz[0]], [b.wxyz[1], b.wxyz[2], b.wxyz[3], b.wxyz[0]]]
    )
    R = Slerp([0.0, 1.0], rotations)([e]).as_matrix()[0]
    position = (1 - e) * a.position + e * b.position
    distance = (1 - e) * np.linalg.norm(a.look_at - a.position) + e * np.linalg.norm(
        b.look_at - b.position
    )
    return ViewerPose(
        position=position,
        wxyz=wxyz_from_matrix(R),
        fov_y=(1 - e) * a.fov_y + e * b.fov_y,
        look_at=position + max(distance, 1e-3) * R[:, 2],
        up=-R[:, 1],
    )


def arm_joint_points(
    table: DHTable, q: ArrayLike, T_world_base: ArrayLike, T_flange_tool: ArrayLike | None = None
) -> FloatArray:
    """World positions ``(n + 1 [+ 1], 3)`` of the arm's frame origins base .. flange (and the
    tool point when ``T_flange_tool`` is given), for drawing the links as segments."""
    frames = np.asarray(T_world_base, dtype=float) @ table.frames(q)
    points = frames[:, :3, 3]
    if T_flange_tool is not None:
        tool = frames[-1] @ np.asarray(T_flange_tool, dtype=float)
        points = np.vstack([points, tool[:3, 3]])
    return points


def arm_link_segments(points: ArrayLike) -> FloatArray:
    """Segments ``(m, 2, 3)`` joining consecutive joint points, zero-length links skipped."""
    p = np.asarray(points, dtype=float)
    segments = [(a, b) for a, b in itertools.pairwise(p) if np.linalg.norm(b - a) > 1e-6]
    return np.array(segments, dtype=float).reshape(-1, 2, 3)


# -- rays and surfaces ---------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Mesh:
    """Triangles in the world: ``vertices`` ``(n, 3)`` m, ``faces`` ``(m, 3)`` vertex indices."""

    name: str
    vertices: FloatArray
    faces: NDArray[np.int64]


def box_mesh(name: str, T_world_box: ArrayLike, size: ArrayLike) -> Mesh:
    """The twelve triangles of a box centred at ``T_world_box`` with edge lengths ``size``."""
    half = np.asarray(size, dtype=float) / 2.0
    corners = (
        np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float)
        * half
    )
    T = np.asarray(T_world_box, dtype=float)
    vertices = corners @ T[:3, :3].T + T[:3, 3]
    faces = np.array(
        [
            [0, 1, 3],
            [0, 3, 2],
            [4, 6, 7],
            [4, 7, 5],  # x- , x+
            [0, 4, 5],
            [0, 5, 1],
            [2, 3, 7],
            [2, 7, 6],  # y- , y+
            [0, 2, 6],
            [0, 6, 4],
            [1, 5, 7],
            [1, 7, 3],  # z- , z+
        ],
        dtype=np.int64,
    )
    return Mesh(name, vertices, faces)


def cylinder_mesh(
    name: str, T_world_cylinder: ArrayLike, radius: float, length: float, segments: int = 24
) -> Mesh:
    """A closed cylinder (``segments`` sides) about the pose's z axis, centred on the pose."""
    angles = np.linspace(0.0, 2 * np.pi, segments, endpoint=False)
    ring = np.stack([radius * np.cos(angles), radius * np.sin(angles)], axis=1)
    bottom = np.hstack([ring, np.full((segments, 1), -length / 2)])
    top = np.hstack([ring, np.full((segments, 1), length / 2)])
    centres = np.array([[0.0, 0.0, -length / 2], [0.0, 0.0, length / 2]])
    local = np.vstack([bottom, top, centres])
    T = np.asarray(T_world_cylinder, dtype=float)
    faces = []
    for k in range(segments):
        j = (k + 1) % segments
        faces += [[k, j, segments + j], [k, segments + j, segments + k]]
        faces += [[2 * segments, j, k], [2 * segments + 1, segments + k, segments + j]]
    return Mesh(name, local @ T[:3, :3].T + T[:3, 3], np.array(faces, dtype=np.int64))


def quad_mesh(name: str, corners: ArrayLike) -> Mesh:
    """Two triangles of a planar quadrilateral given by four corners in order."""
    return Mesh(
        name,
        np.asarray(corners, dtype=float).reshape(4, 3),
        np.array([[0, 1, 2], [0, 2, 3]], dtype=np.int64),
    )


@dataclass(frozen=True)
class RayHit:
    """Where a ray first meets a surface: the mesh's name, the point (m) and the distance (m)."""

    name: str
    point: FloatArray
    distance: float


def ray_mesh_distances(origin: ArrayLike, direction: ArrayLike, mesh: Mesh) -> FloatArray:
    """Distance along the unit ray to every triangle (``inf`` where it misses; Moller-Trumbore,
    both faces)."""
    o = np.asarray(origin, dtype=float)
    d = np.asarray(direction, dtype=float)
    d = d / np.linalg.norm(d)
    tri = mesh.vertices[mesh.faces]
    e1 = tri[:, 1] - tri[:, 0]
    e2 = tri[:, 2] - tri[:, 0]
    p = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, p)
    ok = np.abs(det) > 1e-12
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = o - tri[:, 0]
    u = np.einsum("ij,ij->i", s, p) * inv
    q = np.cross(s, e1)
    v = (q @ d) * inv
    t = np.einsum("ij,ij->i", e2, q) * inv
    hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 1e-9)
    return np.where(hit, t, np.inf)


def ray_hit(origin: ArrayLike, direction: ArrayLike, meshes: list[Mesh]) -> RayHit | None:
    """The nearest surface point a ray from ``origin`` along ``direction`` hits, or None."""
    d = np.asarray(direction, dtype=float)
    norm = float(np.linalg.norm(d))
    if not np.isfinite(norm) or norm == 0.0:
        raise ValueError(f"a ray needs a finite, non-zero direction, got {d}")
    d = d / norm
    best: RayHit | None = None
    for mesh in meshes:
        distances = ray_mesh_distances(origin, d, mesh)
        k = int(np.argmin(distances)) if len(distances) else -1
        if k >= 0 and np.isfinite(distances[k]) and (best is None or distances[k] < best.distance):
            point = np.asarray(origin, dtype=float) + distances[k] * d
            best = RayHit(mesh.name, point, float(distances[k]))
    return best


def pixel_of_ray_on_image(
    origin: ArrayLike, direction: ArrayLike, frustum: Frustum, depth: float
) -> FloatArray | None:
    """The image pixel a click ray meets on a frustum's image plane drawn at ``depth`` (m), or
    None when the ray misses the plane or the image: how a click on an image in the 3-D view
    becomes a pixel of that image."""
    o = np.asarray(origin, dtype=float)
    d = np.asarray(direction, dtype=float)
    R, c = frustum.T_world_camera[:3, :3], frustum.T_world_camera[:3, 3]
    o_cam = R.T @ (o - c)
    d_cam = R.T @ d
    if abs(d_cam[2]) < 1e-12:
        return None
    t = (depth - o_cam[2]) / d_cam[2]
    if t <= 0:
        return None
    p = o_cam + t * d_cam
    uv = (frustum.drawn_K @ (p / p[2]))[:2]
    if not (0 <= uv[0] <= frustum.width and 0 <= uv[1] <= frustum.height):
        return None
    return uv
