"""A second, independent scene generator for the snake: a coloured patch on real photographs.

The project's own renderer (:mod:`umbra.modules.vision.scene`) draws one photograph (``coffee``)
under a camera looking straight down, with motion blur and additive noise; a snake tuned on it can
fit that renderer rather than cameras. This generator makes the same *class* of image by other
means, so that tuning and scoring can be split:

- **Backgrounds**: the photographs scikit-image ships (no download), split once into
  :data:`TUNING_PHOTOS` and :data:`HELD_OUT_PHOTOS`. A tuning loop must only ever draw from the
  first; the second scores. Each frame shows a random crop of its photograph under a random
  plane homography (a table seen obliquely), at 1 to 3 image pixels per photo pixel, mirrored
  where the crop runs out.
- **Patch**: a rectangle of random size and aspect in a plane tilted up to 40 degrees from the
  image plane, turned by any angle: a convex quadrilateral. Its exact pixel coverage is
  measured by point sampling (``SAMPLES``² points in every pixel the outline crosses, whole
  pixels elsewhere), which is unbiased and shares no code with the project's analytic
  coverage. The ground truth is the quadrilateral itself, its area the shoelace area.
  The colour is drawn from a palette of saturated paints, with a mild shading across the patch.
- **Camera**, in the order of the physics, on linear radiance in gray-level units: a smooth
  illumination gradient over the whole scene; a lighting gain (0.55 to 1.45) and a colour cast
  (per-channel gains 0.8 to 1.25); lens blur (Gaussian, sigma 0.4 to 1.3 px) and sometimes a
  short motion blur; shot and read noise (sigma up to ~8 gray levels at mid-gray); clipping;
  on an sRGB camera the sRGB curve; 8-bit quantization; and JPEG compression (quality 75 to 95)
  on half the frames.

Frames are 1920 x 1080 by default. Pixel centres at integer coordinates, u right, v down;
images H x W x 3 uint8 BGR.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np
from numpy.typing import NDArray

from umbra.modules.vision.transfer import Encoding

FloatArray = NDArray[np.float64]

#: Photographs a tuning loop may use.
TUNING_PHOTOS = ("coffee", "chelsea", "astronaut", "brick", "grass", "coins")
#: Photographs kept for scoring only: no parameter is ever chosen by looking at them.
HELD_OUT_PHOTOS = ("rocket", "immunohistochemistry", "camera", "gravel", "hubble_deep_field")

#: Patch paints (RGB, 0..255 at gain 1).
PALETTE = (
    (30, 170, 60),
    (200, 40, 40),
    (40, 70, 190),
    (230, 140, 20),
    (150, 40, 170),
    (20, 150, 160),
    (210, 200, 30),
)

#: Point samples per pixel side where the outline crosses a pixel.
SAMPLES = 16


@dataclass(frozen=True)
class CameraConditions:
    """How hard the camera makes the frame: the lighting ``gain_range``; the patch's long side
    ``span_px`` (low, high) in the image [px]; ``noise_scale`` times the shot and read noise;
    JPEG on a ``jpeg_share`` of the frames at a quality drawn from ``jpeg_quality`` (low,
    high, both included); the codes written are proportional to light (``linear``) or the
    light encoded by the sRGB curve before quantization (``srgb``, as webcams write). The
    defaults are the generator's own frames."""

    gain_range: tuple[float, float] = (0.55, 1.45)
    span_px: tuple[float, float] = (160.0, 520.0)
    noise_scale: float = 1.0
    jpeg_share: float = 0.5
    jpeg_quality: tuple[int, int] = (75, 95)
    encoding: Encoding = "linear"


#: Frames harder than the tuning ones: JPEG at quality 70 to 95 on every frame, twice the
#: sensor noise, and gains up to 1.6 that clip the patch's brightest channel.
HARSH = CameraConditions(
    gain_range=(0.55, 1.6), noise_scale=2.0, jpeg_share=1.0, jpeg_quality=(70, 95)
)


@dataclass(frozen=True, eq=False)
class PhotoFrame:
    """A rendered frame: ``image`` (H x W x 3 uint8 BGR), the patch ``corners`` (4 x 2 px, the
    ground truth polygon), its ``area_px2`` (shoelace), the ``photo`` name, the patch ``rgb``
    and a short ``conditions`` record (gain, cast, blur, noise, JPEG quality)."""

    image: NDArray[np.uint8]
    corners: FloatArray
    area_px2: float
    photo: str
    rgb: tuple[int, int, int]
    conditions: dict


@lru_cache(maxsize=16)
def load_photo(name: str) -> NDArray[np.uint8]:
    """The scikit-image photograph ``name`` as H x W x 3 uint8 BGR (gray ones repeated)."""
    from skimage import data

    image = np.asarray(getattr(data, name)())
    if image.ndim == 2:
        image = np.repeat(image[:, :, None], 3, axis=2)
    image = image[:, :, :3]
    if image.dtype != np.uint8:
        image = (255.0 * image / max(float(image.max()), 1e-9)).astype(np.uint8)
    out = np.ascontiguousarray(image[:, :, ::-1])
    out.flags.writeable = False
    return out


def _background(photo: NDArray[np.uint8], size: tuple[int, int], rng: np.random.Generator):
    """The photograph warped onto the frame (float32 H x W x 3) by a random homography."""
    width, height = size
    rows, cols = photo.shape[:2]
    scale = rng.uniform(1.0, 3.0)  # image pixels per photo pixel
    # The frame's corners, pulled back into the photo: a square-ish region turned and skewed.
    span = np.array([width, height], dtype=np.float64) / scale
    centre = np.array([cols, rows]) * rng.uniform(0.3, 0.7, 2)
    angle = rng.uniform(-np.pi, np.pi)
    c, s = np.cos(angle), np.sin(angle)
    frame_corners = np.array([[0, 0], [width, 0], [width, height], [0, height]], np.float64)
    local = (frame_corners / [width, height] - 0.5) * span
    local *= 1.0 + rng.uniform(-0.15, 0.15, (4, 1))  # keystone: a plane seen obliquely
    photo_corners = centre + local @ np.array([[c, s], [-s, c]])
    H = cv2.getPerspectiveTransform(
        photo_corners.astype(np.float32), frame_corners.astype(np.float32)
    )
    warped = cv2.warpPerspective(
        photo, H, (width, height), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT_101
    )
    return warped.astype(np.float32)


def _patch_corners(
    size: tuple[int, int], rng: np.random.Generator, span_range=(160.0, 520.0)
) -> FloatArray:
    """A w x h rectangle on a plane tilted up to 40 deg, seen through a pin-hole camera, its
    long side about ``span_range`` (low, high) px."""
    width, height = size
    focal = rng.uniform(0.75, 1.15) * width
    w = 0.06
    h = w * rng.uniform(0.5, 1.0)
    tilt = np.deg2rad(rng.uniform(0.0, 40.0))
    axis = rng.uniform(-np.pi, np.pi)
    yaw = rng.uniform(-np.pi, np.pi)
    local = np.array([[-w, -h], [w, -h], [w, h], [-w, h]]) / 2.0
    c, s = np.cos(yaw), np.sin(yaw)
    local = local @ np.array([[c, s], [-s, c]])
    points = np.column_stack([local, np.zeros(4)])
    k = np.array([np.cos(axis), np.sin(axis), 0.0])  # tilt about an axis in the plane
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    R = np.eye(3) + np.sin(tilt) * K + (1 - np.cos(tilt)) * K @ K
    span_px = rng.uniform(*span_range)  # the patch's long side in the image, roughly
    depth = focal * w / span_px
    camera = points @ R.T + np.array([0.0, 0.0, depth])
    uv = focal * camera[:, :2] / camera[:, 2:3]
    extent = np.ptp(uv, axis=0)
    room = np.array([width, height]) - extent - 120.0
    centre = np.array([width, height]) / 2.0 + rng.uniform(-0.5, 0.5, 2) * np.maximum(room, 0.0)
    return uv - uv.mean(axis=0) + centre


def _shoelace(polygon: FloatArray) -> float:
    u, v = polygon[:, 0], polygon[:, 1]
    return 0.5 * float(np.dot(u, np.roll(v, -1)) - np.dot(np.roll(u, -1), v))


def patch_coverage(corners: FloatArray, shape: tuple[int, int]) -> tuple[NDArray, tuple]:
    """Share of each pixel (float32) covered by the convex polygon ``corners`` (N x 2 px) over
    its bounding box, and that box's (u0, v0). Pixels wholly inside or outside (their centre
    more than sqrt(2)/2 px from every edge line) are 1 or 0; the others are point-sampled on a
    ``SAMPLES`` x ``SAMPLES`` grid."""
    height, width = shape
    points = corners if _shoelace(corners) > 0 else corners[::-1]
    low = np.maximum(np.floor(points.min(axis=0)).astype(int) - 2, 0)
    high = np.minimum(np.ceil(points.max(axis=0)).astype(int) + 3, [width, height])
    u = np.arange(low[0], high[0], dtype=np.float64)
    v = np.arange(low[1], high[1], dtype=np.float64)
    edges = np.roll(points, -1, axis=0) - points
    normals = np.column_stack([edges[:, 1], -edges[:, 0]])
    normals /= np.hypot(normals[:, 0], normals[:, 1])[:, None]  # outward (positive area)
    offsets = np.einsum("ij,ij->i", normals, points)
    # Signed distance of each pixel centre outside each edge line; the polygon is where all <= 0.
    dist = (
        normals[:, 0, None, None] * u[None, None, :] + normals[:, 1, None, None] * v[None, :, None]
    )
    dist -= offsets[:, None, None]
    outside = dist.max(axis=0)
    half_diag = np.sqrt(0.5)
    coverage = (outside <= -half_diag).astype(np.float32)
    rows, cols = np.nonzero(np.abs(outside) < half_diag)
    if rows.size:
        steps = (np.arange(SAMPLES) + 0.5) / SAMPLES - 0.5
        grid_u, grid_v = np.meshgrid(steps, steps)
        su, sv = grid_u.ravel(), grid_v.ravel()
        pu = u[cols][:, None] + su[None, :]
        pv = v[rows][:, None] + sv[None, :]
        inside = np.ones(pu.shape, dtype=bool)
        for normal, offset in zip(normals, offsets, strict=True):
            inside &= normal[0] * pu + normal[1] * pv <= offset
        coverage[rows, cols] = inside.mean(axis=1)
    return coverage, (int(low[0]), int(low[1]))


def _distinct(background: NDArray, corners: FloatArray, rgb, ring_px: float = 40.0) -> bool:
    """True when under 1 % of the background within ``ring_px`` of the patch lies within 25
    gray levels of the patch's colour ray through black (chromaticity offset times R + G + B,
    the colour model's own measure): a patch a colour tracker can be asked to tell from its
    surroundings. (A dark, weakly coloured background is close to every colour ray.)"""
    low = np.maximum(np.floor(corners.min(axis=0) - ring_px).astype(int), 0)
    high = np.ceil(corners.max(axis=0) + ring_px).astype(int)
    region = background[low[1] : high[1], low[0] : high[0]].reshape(-1, 3)
    total = np.maximum(region.sum(axis=1), 1.0)
    rg = np.column_stack([region[:, 2], region[:, 1]]) / total[:, None]
    target = np.array([rgb[0], rgb[1]], dtype=np.float64) / float(sum(rgb))
    close = np.hypot(*(rg - target).T) * total < 25.0
    return float(close.mean()) < 0.01


def render(
    photo: str,
    rng: np.random.Generator,
    size: tuple[int, int] = (1920, 1080),
    conditions: CameraConditions = CameraConditions(),
) -> PhotoFrame:
    """One frame of the patch on ``photo`` (a scikit-image name) at ``size`` (W, H) under
    ``conditions``."""
    camera = conditions
    width, height = size
    source = load_photo(photo)
    for _ in range(50):
        scene = _background(source, size, rng)
        corners = _patch_corners(size, rng, camera.span_px)
        rgb = PALETTE[int(rng.integers(len(PALETTE)))]
        if _distinct(scene, corners, rgb):
            break
    coverage, (u0, v0) = patch_coverage(corners, (height, width))
    rows, cols = coverage.shape
    region = scene[v0 : v0 + rows, u0 : u0 + cols]
    # The paint with a mild shading across the patch (+-6 %), blended by coverage.
    vv, uu = np.mgrid[0:rows, 0:cols].astype(np.float32)
    tilt = rng.uniform(-0.06, 0.06, 2) / np.array([cols, rows], dtype=np.float32)
    shade = 1.0 + tilt[0] * (uu - cols / 2) + tilt[1] * (vv - rows / 2)
    paint = np.array(rgb[::-1], dtype=np.float32) * rng.uniform(0.9, 1.1)
    region += (shade[:, :, None] * paint - region) * coverage[:, :, None]
    # Illumination: a smooth gradient over the scene, then the gain and the cast.
    gain = rng.uniform(*camera.gain_range)
    cast = rng.uniform(0.8, 1.25, 3)
    gy, gx = np.mgrid[0:height:8, 0:width:8].astype(np.float32)
    slope = rng.uniform(-0.2, 0.2, 2)
    field = 1.0 + slope[0] * (gx / width - 0.5) + slope[1] * (gy / height - 0.5)
    field = cv2.resize(field, (width, height), interpolation=cv2.INTER_LINEAR)
    scene *= field[:, :, None]
    scene *= (gain * cast[::-1]).astype(np.float32)
    # The lens, then (sometimes) a short motion during the exposure.
    lens_sigma = rng.uniform(0.4, 1.3)
    scene = cv2.GaussianBlur(scene, (0, 0), lens_sigma)
    motion = rng.uniform(0.0, 2.0) if rng.random() < 0.5 else 0.0
    if motion >= 0.5:
        from umbra.modules.vision.lighting import motion_blur_kernel

        kernel = motion_blur_kernel(motion, rng.uniform(0.0, np.pi))
        scene = cv2.filter2D(scene, -1, kernel, borderType=cv2.BORDER_REFLECT)
    # Shot noise (variance proportional to the signal) and read noise, in gray levels.
    read = rng.uniform(1.0, 4.0)
    shot = rng.uniform(0.05, 0.25)  # gray levels² per gray level
    sigma = camera.noise_scale * np.sqrt(read * read + shot * np.maximum(scene, 0.0))
    scene += sigma * rng.standard_normal(scene.shape, dtype=np.float32)
    scene = np.clip(scene, 0.0, 255.0)
    if camera.encoding == "srgb":
        scene = _srgb_codes(scene)
    image = np.rint(scene).astype(np.uint8)
    low, high = camera.jpeg_quality
    quality = int(rng.integers(low, high + 1)) if rng.random() < camera.jpeg_share else 0
    if quality:
        _, encoded = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, quality])
        image = cv2.imdecode(encoded, cv2.IMREAD_COLOR)
    record = {
        "gain": float(gain),
        "cast_rgb": [float(c) for c in cast],
        "lens_sigma_px": float(lens_sigma),
        "motion_px": float(motion),
        "read_noise": float(read),
        "shot_noise": float(shot),
        "jpeg_quality": quality,
    }
    return PhotoFrame(image, corners, abs(_shoelace(corners)), photo, rgb, record)


def _srgb_codes(light: NDArray[np.float32]) -> NDArray[np.float32]:
    """sRGB codes (0..255) of ``light`` (0..255), by IEC 61966-2-1's curve. Written here from
    the standard, apart from :mod:`umbra.modules.vision.transfer`, so that a mistake there does
    not cancel out against this generator."""
    x = light / np.float32(255.0)
    encoded = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)
    return (255.0 * encoded).astype(np.float32)


def frames(
    photos: tuple[str, ...],
    count: int,
    seed: int,
    size=(1920, 1080),
    conditions: CameraConditions = CameraConditions(),
):
    """``count`` frames cycling through ``photos``, reproducible from ``seed``."""
    rng = np.random.default_rng(seed)
    return [render(photos[i % len(photos)], rng, size, conditions=conditions) for i in range(count)]
