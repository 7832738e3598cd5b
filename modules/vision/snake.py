"""Statistical pressure snake (Ivins & Porrill statistics, Perrin & Smith pressure model).

The snake is a closed polygon of vertices ``(u, v)`` [px] on the image. At every iteration each
vertex moves along its outward normal by a *pressure* and towards the midpoint of its two
neighbours by *tension*:

    P_i  <-  P_i + step_px * p_i * n_i + tension * ((P_{i-1} + P_{i+1}) / 2 - P_i)

The pressure comes from the color statistics of a small window of pixels around the vertex:
each pixel in the window votes "target" when its chromaticity lies within ``k_sigma``
Mahalanobis of the target model (see :mod:`modules.vision.color`), and ``p_i = 2 f - 1`` where
``f`` is the area-weighted fraction of target pixels. Deep inside the target ``p = +1`` (the
snake pushes out), in the background ``p = -1`` (it pulls in), and across an edge ``p`` falls
linearly over the window's width, so a vertex comes to rest where half its window is target:
on the edge, to a fraction of a pixel, whatever the blur. (The gate counts a mixed edge pixel
as target only when it is mostly patch, so the contour settles a few tenths of a pixel inside
a sharp edge: about 2 % of the area of a 160 x 110 px patch.) This is Ivins & Porrill's sign
rule (push out within k sigma, in outside) made continuous by the window.

Tension (the discrete Laplacian) keeps the segments even and the contour smooth; it rounds the
corners of a rectangle by a radius of about ``tension * segment² / (2 step_px)``.

The polygon is resampled evenly by arc length whenever a segment leaves
``[min_segment_px, max_segment_px]``, so the vertex count follows the contour's length. The work
of an iteration is proportional to the number of vertices: only a (2r+2)² block of pixels
around each vertex is read.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from modules.vision.color import ColorModel, gate_test, offset_matrix
from modules.vision.polygon import (
    as_polygon,
    circle,
    resample_uniform,
    segment_lengths,
    signed_area,
    with_positive_area,
)
from modules.vision.sampling import window_blocks

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class SnakeParams:
    """Parameters of the snake. Lengths in pixels, counts in iterations or vertices.

    - ``k_sigma``: Mahalanobis radius of the target color [standard deviations].
    - ``min_gray``: pixels darker than this mean gray level (0..255) never count as target.
    - ``step_px``: largest pressure displacement of a vertex per iteration [px].
    - ``tension``: fraction of the way to the neighbours' midpoint per iteration (0..0.5).
    - ``window_radius_px``: half-width of the pixel window read around each vertex [px].
    - ``min_segment_px`` / ``max_segment_px``: segment length bounds that trigger resampling [px].
    - ``min_vertices`` / ``max_vertices``: bounds on the vertex count.
    - ``seed_radius_px`` / ``seed_vertices``: initial circle of a point seed.
    - ``max_iterations``: iteration budget when acquiring from a seed.
    - ``track_iterations``: iteration budget per new frame when tracking.
    - ``converge_px``: the snake has converged when no vertex moved more than this [px].
    - ``adapt_rate``: weight of new interior samples in the color model per frame (0 = never).
    - ``adapt_inset_px``: how far inside the contour the adaptation samples are read [px].
    """

    k_sigma: float = 3.0
    min_gray: float = 20.0
    step_px: float = 2.0
    tension: float = 0.3
    window_radius_px: int = 2
    min_segment_px: float = 5.0
    max_segment_px: float = 12.0
    min_vertices: int = 8
    max_vertices: int = 400
    seed_radius_px: float = 5.0
    seed_vertices: int = 12
    max_iterations: int = 300
    track_iterations: int = 12
    converge_px: float = 0.1
    adapt_rate: float = 0.1
    adapt_inset_px: float = 6.0

    def __post_init__(self) -> None:
        checks = [
            (self.k_sigma > 0, "k_sigma must be > 0"),
            (self.step_px > 0, "step_px must be > 0"),
            (0.0 <= self.tension <= 0.5, "tension must be within [0, 0.5] (explicit smoothing)"),
            (self.window_radius_px >= 0, "window_radius_px must be >= 0"),
            (
                0 < self.min_segment_px < self.max_segment_px,
                "need 0 < min_segment_px < max_segment_px",
            ),
            (3 <= self.min_vertices <= self.max_vertices, "need 3 <= min_vertices <= max_vertices"),
            (self.seed_radius_px > 0, "seed_radius_px must be > 0"),
            (self.seed_vertices >= 3, "seed_vertices must be >= 3"),
            (self.max_iterations >= 1, "max_iterations must be >= 1"),
            (self.track_iterations >= 1, "track_iterations must be >= 1"),
            (self.converge_px > 0, "converge_px must be > 0"),
            (0.0 <= self.adapt_rate <= 1.0, "adapt_rate must be within [0, 1]"),
        ]
        for ok, message in checks:
            if not ok:
                raise ValueError(f"snake parameters: {message}")

    @property
    def target_segment_px(self) -> float:
        """Segment length [px] the resampler aims at."""
        return 0.5 * (self.min_segment_px + self.max_segment_px)


@dataclass(frozen=True, eq=False)
class SnakeResult:
    """Outcome of evolving a snake: ``vertices`` (N x 2, px), iterations run, whether it converged
    (last motion below ``converge_px``), the largest vertex motion of the last iteration [px],
    and ``collapsed`` when the contour shrank to nothing."""

    vertices: FloatArray
    iterations: int
    converged: bool
    last_motion_px: float
    collapsed: bool = False


def seed_point(center_uv: ArrayLike, params: SnakeParams) -> FloatArray:
    """Initial vertices for growing from a point: a small circle around ``center_uv``."""
    return circle(center_uv, params.seed_radius_px, params.seed_vertices)


def seed_region(polygon: ArrayLike, params: SnakeParams) -> FloatArray:
    """Initial vertices for collapsing onto a target from a region (rectangle or polygon)."""
    region = with_positive_area(as_polygon(polygon))
    return _resample(region, params)


def outward_normals(vertices: FloatArray) -> FloatArray:
    """Unit outward normals at the vertices (from the neighbours' chord), for either order."""
    chord = np.roll(vertices, -1, axis=0) - np.roll(vertices, 1, axis=0)
    normal = np.column_stack([chord[:, 1], -chord[:, 0]])
    if signed_area(vertices) < 0.0:
        normal = -normal
    length = np.hypot(normal[:, 0], normal[:, 1])
    return normal / np.maximum(length, 1e-12)[:, None]


def pressure(
    image: NDArray[np.uint8], vertices: FloatArray, model: ColorModel, params: SnakeParams
) -> FloatArray:
    """Pressure in [-1, 1] at each vertex: 2 x (weighted fraction of target pixels) - 1."""
    return _pressure(image.reshape(-1, image.shape[2]), image.shape, vertices, model, params)


def _pressure(
    flat: NDArray[np.uint8],
    shape: tuple[int, ...],
    vertices: FloatArray,
    model: ColorModel,
    params: SnakeParams,
) -> FloatArray:
    """:func:`pressure` on the image viewed as (H W) x 3."""
    height, width = shape[:2]
    radius = params.window_radius_px
    span = 2 * radius + 2
    base = np.floor(vertices)
    frac = vertices - base
    base = base.astype(np.intp) - radius
    steps = np.arange(span)
    cols = np.clip(base[:, 0:1] + steps, 0, width - 1)
    rows = np.clip(base[:, 1:2] + steps, 0, height - 1) * width
    index = (rows[:, :, None] + cols[:, None, :]).ravel()
    pixels = np.take(flat, index, axis=0).astype(np.float32)
    offsets = pixels @ offset_matrix(model)  # (N B B, 3): offsets from the color ray, and sum
    target = gate_test(model, offsets, params.k_sigma, params.min_gray)
    target = target.reshape(len(vertices), span, span)
    # Area weights of the box window: 1 - f on the first row/column, f on the last.
    w_u = np.ones((len(vertices), span))
    w_v = np.ones((len(vertices), span))
    w_u[:, 0] = 1.0 - frac[:, 0]
    w_u[:, -1] = frac[:, 0]
    w_v[:, 0] = 1.0 - frac[:, 1]
    w_v[:, -1] = frac[:, 1]
    per_row = np.einsum("nij,nj->ni", target.astype(np.float64), w_u)
    fraction = np.einsum("ni,ni->n", per_row, w_v) / float((2 * radius + 1) ** 2)
    return 2.0 * fraction - 1.0


def step(
    image: NDArray[np.uint8], vertices: FloatArray, model: ColorModel, params: SnakeParams
) -> tuple[FloatArray, float]:
    """One iteration: move every vertex by pressure and tension; returns (vertices, max motion).

    The motion is measured before resampling; the vertices are kept inside the image.
    """
    return _step(image.reshape(-1, image.shape[2]), image.shape, vertices, model, params)


def _step(
    flat: NDArray[np.uint8],
    shape: tuple[int, ...],
    vertices: FloatArray,
    model: ColorModel,
    params: SnakeParams,
) -> tuple[FloatArray, float]:
    height, width = shape[:2]
    p = _pressure(flat, shape, vertices, model, params)
    before = np.roll(vertices, 1, axis=0)
    after = np.roll(vertices, -1, axis=0)
    chord = after - before
    # Shoelace sign: positive area means the outward normal is (chord_v, -chord_u).
    twice_area = np.dot(vertices[:, 0], after[:, 1]) - np.dot(after[:, 0], vertices[:, 1])
    length = np.hypot(chord[:, 0], chord[:, 1])
    scale = params.step_px * p / np.maximum(length, 1e-12)
    if twice_area < 0.0:
        scale = -scale
    motion = params.tension * (0.5 * (before + after) - vertices)
    motion[:, 0] += scale * chord[:, 1]
    motion[:, 1] -= scale * chord[:, 0]
    moved = vertices + motion
    np.clip(moved[:, 0], 0.0, width - 1.0, out=moved[:, 0])
    np.clip(moved[:, 1], 0.0, height - 1.0, out=moved[:, 1])
    largest = float(np.sqrt(np.max(motion[:, 0] ** 2 + motion[:, 1] ** 2)))
    return moved, largest


def needs_resampling(vertices: FloatArray, params: SnakeParams) -> bool:
    """True when a segment is longer than ``max_segment_px`` or, with more than the minimum
    number of vertices, shorter than ``min_segment_px``."""
    lengths = segment_lengths(vertices)
    too_long = bool(lengths.max() > params.max_segment_px)
    too_short = bool(lengths.min() < params.min_segment_px)
    return too_long or (too_short and vertices.shape[0] > params.min_vertices)


def _resample(vertices: FloatArray, params: SnakeParams) -> FloatArray:
    perimeter = float(segment_lengths(vertices).sum())
    count = round(perimeter / params.target_segment_px)
    count = int(np.clip(count, params.min_vertices, params.max_vertices))
    return resample_uniform(vertices, count)


def is_collapsed(vertices: FloatArray, params: SnakeParams) -> bool:
    """True when the contour has shrunk below one window: nothing is left to track."""
    extent = np.ptp(vertices, axis=0)
    return bool(extent.max() < 2.0 * params.window_radius_px + 1.0)


def evolve(
    image: NDArray[np.uint8],
    vertices: ArrayLike,
    model: ColorModel,
    params: SnakeParams,
    max_iterations: int | None = None,
) -> SnakeResult:
    """Iterate from ``vertices`` until converged, collapsed or ``max_iterations`` (default
    ``params.max_iterations``). ``image`` is H x W x 3 uint8 BGR."""
    if image.ndim != 3 or image.shape[2] != 3:
        raise ValueError(f"the snake needs an H x W x 3 color image, got shape {image.shape}")
    budget = params.max_iterations if max_iterations is None else max_iterations
    current = as_polygon(vertices)
    if current.shape[0] < 3:
        raise ValueError(f"a snake needs at least 3 vertices, got {current.shape[0]}")
    if needs_resampling(current, params):
        current = _resample(current, params)
    # One H W x 3 view of the pixels for np.take (a copy only for a non-contiguous image).
    flat = np.ascontiguousarray(image).reshape(-1, image.shape[2])
    motion = np.inf
    iterations = 0
    for iterations in range(1, budget + 1):
        current, motion = _step(flat, image.shape, current, model, params)
        if is_collapsed(current, params):
            return SnakeResult(current, iterations, False, motion, collapsed=True)
        if needs_resampling(current, params):
            current = _resample(current, params)
            continue
        if motion < params.converge_px:
            return SnakeResult(current, iterations, True, motion)
    return SnakeResult(current, iterations, False, motion)


def acquire(
    image: NDArray[np.uint8], seed_uv: ArrayLike, model: ColorModel, params: SnakeParams
) -> SnakeResult:
    """Grow a snake from a point seed until it converges (``params.max_iterations`` at most)."""
    return evolve(image, seed_point(seed_uv, params), model, params)


def track(
    image: NDArray[np.uint8], vertices: ArrayLike, model: ColorModel, params: SnakeParams
) -> SnakeResult:
    """Follow the target into a new frame: a few iterations from the previous contour."""
    return evolve(image, vertices, model, params, max_iterations=params.track_iterations)


def seed_samples(
    image: NDArray[np.uint8], center_uv: ArrayLike, radius_px: float
) -> NDArray[np.uint8]:
    """The pixels (K x 3 BGR) within ``radius_px`` of ``center_uv``, read by fancy indexing."""
    height, width = image.shape[:2]
    cu, cv = (float(c) for c in np.asarray(center_uv, dtype=np.float64).reshape(2))
    reach = int(np.ceil(radius_px))
    du, dv = np.meshgrid(np.arange(-reach, reach + 1), np.arange(-reach, reach + 1))
    inside = du * du + dv * dv <= radius_px * radius_px
    cols = np.round(cu).astype(int) + du[inside]
    rows = np.round(cv).astype(int) + dv[inside]
    ok = (cols >= 0) & (cols < width) & (rows >= 0) & (rows < height)
    if not np.any(ok):
        raise ValueError(f"seed point ({cu:.1f}, {cv:.1f}) is outside the {width}x{height} image")
    return image[rows[ok], cols[ok]]


def interior_samples(
    image: NDArray[np.uint8], vertices: FloatArray, params: SnakeParams
) -> NDArray[np.uint8]:
    """Pixels (K x 3 BGR) in windows ``adapt_inset_px`` inside the contour, one per vertex."""
    inset = vertices - params.adapt_inset_px * outward_normals(vertices)
    pixels, _ = window_blocks(image, inset, max(params.window_radius_px - 1, 0))
    return pixels.reshape(-1, image.shape[2])
