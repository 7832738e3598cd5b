"""The simulated wrist-camera scene: table, tray, tool with its colored patch, distractors,
occluders, and a renderer that images it through a distorted pin-hole camera.

Frames and units: world frame z up, the table is the plane z = 0; lengths in metres, angles in
radians; colors RGB 0..255 in the specification (the rendered image is BGR, OpenCV's order).
The patch is the rectangle |x| <= w/2, |y| <= h/2 in the xy plane of its frame
``T_world_patch``; the tool body is a larger rectangle in the same plane, under the patch. The
camera frame is OpenCV's (x right, y down, z along the optical axis); ``T_world_camera`` is the
camera's pose in the world.

Surfaces are drawn back to front in a fixed order (table, tray, tool, patch, distractors,
world occluders, image occluders): the scene is meant to be seen from above, where this order
is the depth order. The ideal pin-hole image is drawn on a canvas a little larger than the
image, then the lens distortion is applied with one precomputed ``cv2.remap``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from umbra.modules.calib.camera_model import Intrinsics
from umbra.modules.geometry.transforms import transform_points
from umbra.modules.vision.coverage import convex_coverage
from umbra.modules.vision.lighting import Lighting, Sensor
from umbra.modules.vision.polygon import inset_convex, is_convex, signed_area
from umbra.modules.vision.projection import ideal_pixels_of_distorted_grid, project_camera_points

FloatArray = NDArray[np.float64]
RGB = tuple[int, int, int]

#: Labels of the ground-truth label image.
LABEL_NONE, LABEL_PATCH, LABEL_DISTRACTOR, LABEL_OCCLUDER = 0, 1, 2, 3

_NEAR_M = 1e-3
_SUBPIXEL_BITS = 4
#: cv2.fillPoly covers the pixels an edge touches, so a filled polygon comes out larger than the
#: polygon by about this much on every side [px] (measured on random rectangles: 0.66 px with
#: LINE_AA, 0.45 px with LINE_8). Convex polygons are inset by it before filling, so that the
#: drawn area matches the true area and the ground truth agrees with the image.
_FILL_GROWTH_AA_PX = 0.65
_FILL_GROWTH_LABEL_PX = 0.45
#: Supersampling of the exact fill (patch, distractors, tool, occluders).
_SUPERSAMPLE = 4


def pose(xyz: ArrayLike = (0.0, 0.0, 0.0), yaw_rad: float = 0.0) -> FloatArray:
    """A 4x4 pose translated by ``xyz`` [m] and turned by ``yaw_rad`` about its z axis."""
    c, s = np.cos(yaw_rad), np.sin(yaw_rad)
    T = np.eye(4)
    T[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    T[:3, 3] = np.asarray(xyz, dtype=np.float64).reshape(3)
    return T


def camera_looking_down(target_xyz: ArrayLike, height_m: float, yaw_rad: float = 0.0) -> FloatArray:
    """``T_world_camera`` of a camera ``height_m`` above ``target_xyz`` looking straight down;
    at yaw 0 the image u axis is world +x and v is world -y."""
    T = np.eye(4)
    c, s = np.cos(yaw_rad), np.sin(yaw_rad)
    x_axis = np.array([c, s, 0.0])
    z_axis = np.array([0.0, 0.0, -1.0])
    y_axis = np.cross(z_axis, x_axis)
    T[:3, :3] = np.column_stack([x_axis, y_axis, z_axis])
    T[:3, 3] = np.asarray(target_xyz, dtype=np.float64) + np.array([0.0, 0.0, height_m])
    return T


@dataclass(frozen=True, eq=False)
class Occluder:
    """A flat polygon of one color in front of everything: ``polygon`` K x 3 [m] in the world
    (``frame="world"``) or K x 2 [px] in the final image (``frame="image"``)."""

    polygon: FloatArray
    frame: Literal["world", "image"] = "world"
    rgb: RGB = (225, 180, 150)


@dataclass(frozen=True, eq=False)
class Scene:
    """What the camera can see. Colors are RGB 0..255; sizes [m] are (along x, along y)."""

    T_world_patch: FloatArray = field(default_factory=lambda: pose((0.0, 0.0, 0.03)))
    patch_size_m: tuple[float, float] = (0.06, 0.04)
    patch_rgb: RGB = (30, 170, 60)
    patch_present: bool = True
    tool_size_m: tuple[float, float] = (0.10, 0.06)
    tool_offset_m: tuple[float, float] = (0.012, 0.0)
    tool_rgb: RGB = (70, 72, 78)
    tray_center_m: tuple[float, float] = (0.0, 0.0)
    tray_size_m: tuple[float, float] = (0.20, 0.15)
    tray_yaw_rad: float = 0.0
    tray_height_m: float = 0.01
    tray_rgb: RGB = (205, 205, 200)
    table_rgb: RGB = (120, 100, 80)
    background: Literal["flat", "photo"] = "flat"
    photo_center_m: tuple[float, float] = (0.0, 0.0)
    photo_size_m: tuple[float, float] = (0.90, 0.60)
    sky_rgb: RGB = (90, 90, 90)
    distractors: tuple[FloatArray, ...] = ()
    occluders: tuple[Occluder, ...] = ()


#: Unit direction, in the patch's xy plane, of each named patch side.
SIDE_AXES: dict[str, tuple[float, float]] = {
    "+x": (1.0, 0.0),
    "-x": (-1.0, 0.0),
    "+y": (0.0, 1.0),
    "-y": (0.0, -1.0),
}


def distractor_touching(
    T_world_patch: FloatArray,
    patch_size_m: tuple[float, float] = (0.06, 0.04),
    side: Literal["+x", "-x", "+y", "-y"] = "+y",
    slide_m: float = 0.0,
    yaw_rad: float = 0.0,
) -> FloatArray:
    """Pose of a second patch of the same size lying against one side of the patch.

    ``side`` names the patch side it touches; the midpoint of the distractor's facing side sits
    on that side, moved by ``slide_m`` along it, and the distractor is turned by ``yaw_rad``
    about that point (so the two stay in contact, overlapping a little when turned).
    """
    w, h = patch_size_m
    axis = SIDE_AXES[side]
    half_across = 0.5 * (w if axis[0] else h)
    contact = np.array([axis[0], axis[1]]) * half_across
    contact += np.array([abs(axis[1]), abs(axis[0])]) * slide_m
    c, s = np.cos(yaw_rad), np.sin(yaw_rad)
    out = np.array([axis[0], axis[1]]) * half_across
    centre = contact + np.array([c * out[0] - s * out[1], s * out[0] + c * out[1]])
    return T_world_patch @ pose((centre[0], centre[1], 0.0), yaw_rad)


@dataclass(frozen=True, eq=False)
class RenderedFrame:
    """A rendered image with its ground truth.

    ``image`` H x W x 3 uint8 BGR; ``patch_polygon`` (N x 2, px) the patch outline in the
    distorted image (edges sampled densely, so curved by the distortion), starting at the patch
    corner (-w/2, -h/2) and running through the corners (+w/2, -h/2), (+w/2, +h/2), (-w/2, +h/2)
    at indices 0, n, 2n, 3n; ``patch_corners`` (4 x 2, px); ``patch_visible_fraction`` the
    share of the patch's image area that is seen (not occluded, inside the image);
    ``labels`` H x W uint8 (0 other, 1 patch, 2 distractor, 3 occluder).
    """

    image: NDArray[np.uint8]
    patch_polygon: FloatArray
    patch_corners: FloatArray
    patch_visible_fraction: float
    labels: NDArray[np.uint8]


def patch_outline(size_m: tuple[float, float], per_edge: int) -> FloatArray:
    """Points (4 per_edge x 3) along the patch border in its own frame, corners first per edge."""
    w, h = size_m
    corners = np.array([[-w / 2, -h / 2], [w / 2, -h / 2], [w / 2, h / 2], [-w / 2, h / 2]])
    t = np.arange(per_edge) / per_edge
    edges = [corners[i] + t[:, None] * (corners[(i + 1) % 4] - corners[i]) for i in range(4)]
    outline = np.vstack(edges)
    return np.column_stack([outline, np.zeros(len(outline))])


def patch_image_outline(
    scene: Scene,
    T_camera_world: FloatArray,
    intrinsics: Intrinsics,
    distortion: ArrayLike,
    per_edge: int,
) -> FloatArray | None:
    """The patch outline in the distorted image (4 ``per_edge`` x 2 px, as
    :attr:`RenderedFrame.patch_polygon`); None when the patch is absent or not wholly in front
    of the camera."""
    if not scene.patch_present:
        return None
    outline = transform_points(scene.T_world_patch, patch_outline(scene.patch_size_m, per_edge))
    outline_camera = transform_points(T_camera_world, outline)
    if np.any(outline_camera[:, 2] <= _NEAR_M):
        return None
    return project_camera_points(outline_camera, intrinsics, distortion)


def _rectangle_3d(center_xy: ArrayLike, size: tuple[float, float], yaw: float, z: float):
    T = pose((*np.asarray(center_xy, dtype=float), z), yaw)
    w, h = size
    local = np.array(
        [[-w / 2, -h / 2, 0], [w / 2, -h / 2, 0], [w / 2, h / 2, 0], [-w / 2, h / 2, 0]]
    )
    return transform_points(T, local)


def _clip_near(points_camera: FloatArray) -> FloatArray:
    """Clip a closed 3-D polygon (camera frame) to z >= near (Sutherland-Hodgman, one plane)."""
    out: list[FloatArray] = []
    count = len(points_camera)
    for i in range(count):
        a, b = points_camera[i], points_camera[(i + 1) % count]
        a_in, b_in = a[2] >= _NEAR_M, b[2] >= _NEAR_M
        if a_in:
            out.append(a)
        if a_in != b_in:
            t = (_NEAR_M - a[2]) / (b[2] - a[2])
            out.append(a + t * (b - a))
    return np.array(out).reshape(-1, 3)


def _fixed_point(polygon_px: FloatArray) -> NDArray[np.int32]:
    return np.round(polygon_px * (1 << _SUBPIXEL_BITS)).astype(np.int32)


def _rgb_to_bgr(rgb: RGB) -> tuple[int, int, int]:
    return (int(rgb[2]), int(rgb[1]), int(rgb[0]))


def _load_photo() -> NDArray[np.uint8]:
    """scikit-image's bundled ``coffee`` photograph (no download), as BGR."""
    import cv2
    from skimage import data

    return cv2.cvtColor(data.coffee(), cv2.COLOR_RGB2BGR)


class SceneRenderer:
    """Renders :class:`Scene` through one camera; the distortion maps are computed once here.

    ``intrinsics`` in pixels (with the image size); ``distortion`` OpenCV's coefficients
    ``[k1, k2, p1, p2(, k3)]`` (None: an ideal lens). Rendering is deterministic
    given the ``rng`` passed to :meth:`render` (only the sensor noise is random). It keeps
    scratch buffers between frames, so one renderer serves one thread.
    """

    def __init__(self, intrinsics: Intrinsics, distortion: ArrayLike | None = None) -> None:
        import cv2

        self.intrinsics = intrinsics
        self.distortion = np.zeros(5) if distortion is None else np.asarray(distortion, float)
        self._photo: NDArray[np.uint8] | None = None
        width, height = intrinsics.width, intrinsics.height
        if not np.any(self.distortion):
            self._offset = np.zeros(2)
            self._canvas_size = (width, height)
            # (linear, nearest-neighbour) cv2.remap maps from the canvas; None: no distortion
            self._maps: tuple[tuple[NDArray, NDArray], tuple[NDArray, NDArray]] | None = None
        else:
            map_u, map_v = ideal_pixels_of_distorted_grid(intrinsics, self.distortion)
            span = np.array([map_u.max() - (width - 1), map_v.max() - (height - 1)])
            low = np.array([-map_u.min(), -map_v.min()])
            limit = np.array([width, height], dtype=float)
            margin = np.ceil(np.clip(np.maximum(span, low), 0.0, limit)) + 2.0
            self._offset = margin
            self._canvas_size = (int(width + 2 * margin[0]), int(height + 2 * margin[1]))
            shifted = (map_u + np.float32(margin[0]), map_v + np.float32(margin[1]))
            self._maps = (
                cv2.convertMaps(*shifted, cv2.CV_16SC2),
                cv2.convertMaps(*shifted, cv2.CV_16SC2, nninterpolation=True),
            )
        self._sensor = Sensor((height, width, 3))
        canvas_width, canvas_height = self._canvas_size
        self._canvas = np.empty((canvas_height, canvas_width, 3), dtype=np.uint8)
        self._canvas_labels = np.empty((canvas_height, canvas_width), dtype=np.uint8)
        self._distorted = np.empty((height, width, 3), dtype=np.uint8)
        K = intrinsics.matrix()
        K[0, 2] += self._offset[0]
        K[1, 2] += self._offset[1]
        self._K_canvas = K
        self._canvas_intrinsics = Intrinsics(
            intrinsics.fx,
            intrinsics.fy,
            intrinsics.skew,
            intrinsics.u0 + self._offset[0],
            intrinsics.v0 + self._offset[1],
            self._canvas_size[0],
            self._canvas_size[1],
        )

    # -- geometry -------------------------------------------------------------------------------

    def project(self, T_world_camera: FloatArray, points_world: ArrayLike) -> FloatArray:
        """Distorted image pixels (N x 2) of world points [m]; raises if one is behind."""
        T_camera_world = np.linalg.inv(T_world_camera)
        points_camera = transform_points(T_camera_world, points_world)
        return project_camera_points(points_camera, self.intrinsics, self.distortion)

    def _canvas_polygon(self, T_camera_world: FloatArray, points_world: FloatArray) -> FloatArray:
        clipped = _clip_near(transform_points(T_camera_world, points_world))
        if len(clipped) < 3:
            return np.empty((0, 2))
        return project_camera_points(clipped, self._canvas_intrinsics)

    # -- drawing --------------------------------------------------------------------------------

    def _draw_table(self, canvas: NDArray[np.uint8], scene: Scene, T_camera_world: FloatArray):
        import cv2

        cv2.rectangle(canvas, (0, 0), self._canvas_size, _rgb_to_bgr(scene.table_rgb), -1)
        R, t = T_camera_world[:3, :3], T_camera_world[:3, 3]
        if scene.background == "photo":
            if self._photo is None:
                self._photo = _load_photo()
            rows, cols = self._photo.shape[:2]
            (cx, cy), (sx, sy) = scene.photo_center_m, scene.photo_size_m
            S = np.array(
                [[sx / cols, 0.0, cx - sx / 2], [0.0, -sy / rows, cy + sy / 2], [0.0, 0.0, 1.0]]
            )
            H = self._K_canvas @ np.column_stack([R[:, 0], R[:, 1], t]) @ S
            cv2.warpPerspective(
                self._photo,
                H,
                self._canvas_size,
                dst=canvas,
                flags=cv2.INTER_LINEAR,
                borderMode=cv2.BORDER_TRANSPARENT,
            )
        self._draw_sky(canvas, scene, T_camera_world)

    def _draw_sky(self, canvas: NDArray[np.uint8], scene: Scene, T_camera_world: FloatArray):
        """Paint the canvas pixels whose rays do not meet the table in front of the camera."""
        import cv2

        R, t = T_camera_world[:3, :3], T_camera_world[:3, 3]
        normal_camera = R[:, 2]  # world z in camera coordinates
        offset = float(normal_camera @ t)  # plane: normal . X_cam = offset
        line = np.linalg.solve(self._K_canvas.T, normal_camera)
        width, height = self._canvas_size
        corners = np.array([[0, 0], [width, 0], [width, height], [0, height]], dtype=float)
        # A ray through pixel x meets the plane at s = offset / (line . x); visible if s > 0.
        sky = np.array([(line @ [u, v, 1.0]) * offset <= 0.0 for u, v in corners])
        if not sky.any():
            return
        polygon: list[FloatArray] = []
        for i in range(4):
            a, b = corners[i], corners[(i + 1) % 4]
            if sky[i]:
                polygon.append(a)
            if sky[i] != sky[(i + 1) % 4]:
                fa, fb = line @ [*a, 1.0], line @ [*b, 1.0]
                polygon.append(a + fa / (fa - fb) * (b - a))
        cv2.fillPoly(
            canvas, [np.round(np.array(polygon)).astype(np.int32)], _rgb_to_bgr(scene.sky_rgb)
        )

    def _fill(self, canvases, polygon_px: FloatArray, color_bgr, label: int) -> None:
        """Fill a polygon fast: OpenCV's anti-aliased fill, inset to keep the true area. Its
        edges may sit up to half a pixel off at some angles: good enough for the tray and the
        tool body, whose edges no test measures."""
        import cv2

        if len(polygon_px) < 3:
            return
        image, labels = canvases
        if is_convex(polygon_px):
            drawn = [_fixed_point(inset_convex(polygon_px, _FILL_GROWTH_AA_PX))]
            labelled = [_fixed_point(inset_convex(polygon_px, _FILL_GROWTH_LABEL_PX))]
        else:
            drawn = labelled = [_fixed_point(polygon_px)]
        cv2.fillPoly(image, drawn, color_bgr, cv2.LINE_AA, _SUBPIXEL_BITS)
        cv2.fillPoly(labels, labelled, label, cv2.LINE_8, _SUBPIXEL_BITS)

    def _fill_exact(self, canvases, polygon_px: FloatArray, color_bgr, label: int) -> None:
        """Fill a polygon with its exact pixel coverage, so its edges are where the ground truth
        says (for the patch, distractors and occluders): a convex polygon's coverage is computed
        analytically (:mod:`umbra.modules.vision.coverage`, area exact to ~0.01 %); another is
        rasterized on a grid ``_SUPERSAMPLE`` times finer over its bounding box and averaged
        down. Blended by coverage; labels where the coverage is at least one half."""
        import cv2

        if len(polygon_px) < 3:
            return
        image, labels = canvases
        height, width = labels.shape
        low = np.maximum(np.floor(polygon_px.min(axis=0)).astype(int) - 1, 0)
        high = np.minimum(np.ceil(polygon_px.max(axis=0)).astype(int) + 2, [width, height])
        if np.any(high <= low):
            return
        (u0, v0), (u1, v1) = low, high
        if is_convex(polygon_px):  # exact coverage, analytically
            weight = convex_coverage(polygon_px, (int(u0), int(v0)), (v1 - v0, u1 - u0))
        else:
            fine = (polygon_px - low + 0.5) * _SUPERSAMPLE - 0.5
            mask = np.zeros(((v1 - v0) * _SUPERSAMPLE, (u1 - u0) * _SUPERSAMPLE), dtype=np.uint8)
            cv2.fillPoly(mask, [_fixed_point(fine)], 255, cv2.LINE_8, _SUBPIXEL_BITS)
            coverage = cv2.resize(mask, (u1 - u0, v1 - v0), interpolation=cv2.INTER_AREA)
            weight = coverage.astype(np.float32) * np.float32(1.0 / 255.0)
        region = image[v0:v1, u0:u1].astype(np.float32)
        region += (np.asarray(color_bgr, dtype=np.float32) - region) * weight[:, :, None]
        image[v0:v1, u0:u1] = np.rint(region).astype(np.uint8)
        labels[v0:v1, u0:u1][weight >= 0.5] = label

    def render(
        self,
        scene: Scene,
        T_world_camera: FloatArray,
        lighting: Lighting | None = None,
        rng: np.random.Generator | None = None,
        outline_points_per_edge: int = 16,
    ) -> RenderedFrame:
        """Image the scene from ``T_world_camera`` (4x4, metres) under ``lighting``."""
        import cv2

        lighting = lighting or Lighting()
        rng = rng if rng is not None else np.random.default_rng(0)
        T_camera_world = np.linalg.inv(np.asarray(T_world_camera, dtype=np.float64))
        canvas = self._canvas
        labels = self._canvas_labels
        labels.fill(LABEL_NONE)
        canvases = (canvas, labels)
        self._draw_table(canvas, scene, T_camera_world)
        tray = _rectangle_3d(
            scene.tray_center_m, scene.tray_size_m, scene.tray_yaw_rad, scene.tray_height_m
        )
        self._fill(
            canvases, self._canvas_polygon(T_camera_world, tray), _rgb_to_bgr(scene.tray_rgb), 0
        )
        tool_local = _rectangle_3d(scene.tool_offset_m, scene.tool_size_m, 0.0, -1e-4)
        tool = transform_points(scene.T_world_patch, tool_local)
        self._fill(
            canvases, self._canvas_polygon(T_camera_world, tool), _rgb_to_bgr(scene.tool_rgb), 0
        )
        patch_local = patch_outline(scene.patch_size_m, 1)
        patch_bgr = _rgb_to_bgr(scene.patch_rgb)
        if scene.patch_present:
            patch = transform_points(scene.T_world_patch, patch_local)
            self._fill_exact(
                canvases, self._canvas_polygon(T_camera_world, patch), patch_bgr, LABEL_PATCH
            )
        for T_world_distractor in scene.distractors:
            distractor = transform_points(np.asarray(T_world_distractor), patch_local)
            self._fill_exact(
                canvases,
                self._canvas_polygon(T_camera_world, distractor),
                patch_bgr,
                LABEL_DISTRACTOR,
            )
        for occluder in scene.occluders:
            if occluder.frame == "world":
                polygon = self._canvas_polygon(T_camera_world, np.asarray(occluder.polygon))
                self._fill_exact(canvases, polygon, _rgb_to_bgr(occluder.rgb), LABEL_OCCLUDER)
        image: NDArray[np.uint8]
        if self._maps is not None:
            (map1, map2), (nearest1, nearest2) = self._maps
            # remap keeps the source's dtype: np.asarray converts nothing.
            distorted = cv2.remap(
                canvas,
                map1,
                map2,
                cv2.INTER_LINEAR,
                dst=self._distorted,
                borderMode=cv2.BORDER_REPLICATE,
            )
            image = np.asarray(distorted, dtype=np.uint8)
            labels = np.asarray(
                cv2.remap(labels, nearest1, nearest2, cv2.INTER_NEAREST), dtype=np.uint8
            )
        else:
            image = canvas
            labels = labels.copy()
        for occluder in scene.occluders:
            if occluder.frame == "image":
                polygon = np.asarray(occluder.polygon, dtype=np.float64).reshape(-1, 2)
                self._fill_exact(
                    (image, labels), polygon, _rgb_to_bgr(occluder.rgb), LABEL_OCCLUDER
                )
        image = self._sensor.apply(image, lighting, rng)
        return self._with_ground_truth(
            scene, T_camera_world, image, labels, outline_points_per_edge
        )

    def _with_ground_truth(self, scene, T_camera_world, image, labels, per_edge) -> RenderedFrame:
        polygon = patch_image_outline(
            scene, T_camera_world, self.intrinsics, self.distortion, per_edge
        )
        if polygon is None:
            empty = np.empty((0, 2))
            return RenderedFrame(image, empty, empty, 0.0, labels)
        area = abs(signed_area(polygon))
        seen = float(np.count_nonzero(labels == LABEL_PATCH))
        visible = min(seen / area, 1.0) if area > 0 else 0.0
        return RenderedFrame(image, polygon, polygon[::per_edge].copy(), visible, labels)
