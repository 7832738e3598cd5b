"""Statistical pressure snake (Ivins & Porrill statistics, Perrin & Smith pressure model).

The snake is a closed polygon of vertices ``(u, v)`` [px] on the image. At every iteration each
vertex moves along its outward normal by a *pressure* and towards the midpoint of its two
neighbours by *tension*:

    P_i  <-  P_i + step_px * p_i * n_i + tension * ((P_{i-1} + P_{i+1}) / 2 - P_i)

The pressure comes from the color statistics of a small window of pixels around the vertex:
each pixel in the window votes "target" when its chromaticity lies within ``k_sigma``
Mahalanobis of the target model (see :mod:`umbra.modules.vision.color`), and ``p_i = 2 f - 1`` where
``f`` is the area-weighted fraction of target pixels. Deep inside the target ``p = +1`` (the
snake pushes out), in the background ``p = -1`` (it pulls in), and across an edge ``p`` falls
linearly over the window's width, so a vertex comes to rest where half its window is target:
on the edge, to a fraction of a pixel, whatever the blur. (The gate counts a mixed edge pixel
as target only when it is mostly patch, so the vertices settle a few tenths of a pixel inside
a sharp edge: 1-3 % of the area of a 160 x 110 px patch, which the edge fit below removes.)
This is Ivins & Porrill's sign rule (push out within k sigma, in outside) made continuous by
the window.

Tension (the discrete Laplacian) keeps the segments even and the contour smooth; it rounds the
corners of a rectangle by a radius of about ``tension * segment² / (2 step_px)``.

The polygon is resampled evenly by arc length whenever a segment leaves
``[min_segment_px, max_segment_px]``, so the vertex count follows the contour's length (up to
``max_vertices``, beyond which the segments grow instead). The work of an iteration is
proportional to the number of vertices: only a (2r+2)² block of pixels around each vertex is
read, straight from the caller's image (a view, never a converted, blurred or copied frame), so
the cost does not depend on the image size.

When the iterations end, the contour is *measured* (:mod:`umbra.modules.vision.edge_fit`): each
vertex is moved along its normal onto the colour edge, fitted to a tenth of a pixel from the edge
profile; when the contour follows a quadrilateral a rectangle can look like (and the snake works
on a fine enough grid), the edge points on each side are put on the curve fitted to that whole
side (:mod:`umbra.modules.vision.straight_sides`), each side is measured again by profiles along
its whole length (:mod:`umbra.modules.vision.side_profiles`), and the corners are put where
those curves meet (:mod:`umbra.modules.vision.side_corners`); and the other sharp convex
corners the even vertices cut off are put back. That measured outline
(:attr:`SnakeResult.contour`) is what the tracker reports; the snake's own vertices
(:attr:`SnakeResult.vertices`) stay where the pressure put them, to start the next frame from.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from umbra.modules.vision.color import ColorModel, is_target
from umbra.modules.vision.edge_fit import (
    EdgeFitParams,
    complete_corners,
    fit_edges,
    measure_near_edge,
    sample_bilinear,
)
from umbra.modules.vision.polygon import (
    as_polygon,
    circle,
    following,
    resample_uniform,
    segment_lengths,
    signed_area,
    with_positive_area,
)
from umbra.modules.vision.pressure import PressureField
from umbra.modules.vision.side_corners import meet_corners
from umbra.modules.vision.side_profiles import remeasure_sides
from umbra.modules.vision.straight_sides import fit_sides
from umbra.modules.vision.transfer import Encoding

FloatArray = NDArray[np.float64]

#: Up to this pixel grid step σ the outline is measured finely: the snake's vertices are
#: resampled at the full grid's segment length before the edge fit (a σ = 2 snake spaces them
#: 17 px apart: a corner it rounds is cut by several pixels, and a short side holds too few
#: points to be fitted), and the sides are fitted whole and meet at the corners. At σ = 1-2 (a
#: patch up to about 300 px a side) a pixel of the outline is a measurable share of the area;
#: beyond, the cost of twice the points is not repaid.
FINE_MEASURE_SCALE = 2
#: A corner is put where the sides meet when the sides' fitted points reach within
#: ``CORNER_REACH_SEGMENTS`` (``max_segment_px``) of that point and the contour passes within
#: ``CORNER_DEPTH_SEGMENTS`` of it, or further where the image reads as the patch up to it: the
#: snake's tension rounds a corner by a few pixels, while an occluder that cuts a corner at 15 %
#: of the sides or more stands further off, with the occluder beyond its chord, and is left for
#: the sanity checks (see :mod:`umbra.modules.vision.side_corners`).
CORNER_DEPTH_SEGMENTS = 0.5
CORNER_REACH_SEGMENTS = 2.0


@dataclass(frozen=True)
class SnakeParams:
    """Parameters of the snake. Lengths in pixels, counts in iterations or vertices. Built from
    validated settings (:class:`umbra.modules.vision.snake_config.SnakeSettings` holds their
    bounds and rules), not checked again here.

    - ``k_sigma``: Mahalanobis radius of the target color [standard deviations].
    - ``min_gray``: pixels darker than this mean gray level (0..255) never count as target.
    - ``dim_share``: nor do pixels darker than this share of the patch's own light on the
      frame (its mean gray level, the tracker measures it inside the contour, as light under
      ``image_encoding``; 0: off): a blurred patch's
      halo on a dark background, or a dark surface of the patch's hue, has its chromaticity.
    - ``step_px``: largest pressure displacement of a vertex per iteration [px].
    - ``tension``: fraction of the way to the neighbours' midpoint per iteration (0..0.5).
    - ``window_radius_px``: half-width of the pixel window read around each vertex [px].
    - ``min_segment_px`` / ``max_segment_px``: segment length bounds that trigger resampling [px].
    - ``min_vertices`` / ``max_vertices``: bounds on the vertex count.
    - ``vertex_budget``: above this many vertices at the target segment length the snake works
      on a coarser grid of pixels (every σ-th), with segments, steps, windows and convergence
      threshold σ times larger, so its cost stays that of at most this many vertices whatever
      the scale of the target in the image (the edge fit still reads full-resolution pixels).
    - ``seed_radius_px`` / ``seed_vertices``: initial circle of a point seed.
    - ``max_iterations``: iteration budget when acquiring from a seed.
    - ``track_iterations``: iteration budget per new frame when tracking.
    - ``converge_px``: the snake has converged when no vertex moved more than this [px].
    - ``adapt_rate``: weight of new interior samples in the color model per frame (0 = never).
    - ``adapt_inset_px``: how far inside the contour the adaptation samples are read [px].
    - ``edge_half_length_px``: half-length of the edge profile fitted along each normal when
      the iterations end [px] (0: report the snake's vertices as they are).
    - ``corner_turn_deg``: a turn sharper than this over one segment is a corner to put back
      [deg].
    - ``side_fit_px``: when the contour follows a view of a rectangle and the outline is
      measured finely (σ up to :data:`FINE_MEASURE_SCALE`: a patch up to about 300 px a side,
      where a single edge point's noise is a measurable share of the area), the edge points
      within this of the quadratic fitted to their side are put on it and the corners where
      the sides meet (0: off; see :mod:`umbra.modules.vision.straight_sides`) [px].
    - ``side_profiles``: with ``side_fit_px`` on, each fitted side is measured again by this
      many profiles along it (at most one a pixel), and its curve fitted to them (0: off; see
      :mod:`umbra.modules.vision.side_profiles`).
    - ``image_encoding``: how the camera's codes stand for light, ``linear`` or ``srgb`` (see
      :mod:`umbra.modules.vision.transfer`): the sub-pixel edge is measured on light.
    - ``min_edge_fraction``: a contour with an edge under fewer of its vertices than this share
      is not on a target (a featureless or colourless image): failed.
    - ``border_margin_px``: a contour that comes this close to the image border is cut by it:
      failed [px].
    - ``min_chroma``: a target colour whose chromaticity lies closer than this to gray
      (r = g = 1/3) cannot be told from a gray scene: failed (unitless).
    - ``max_unconverged_frames``: this many frames in a row without settling while tracking
      mean the snake has lost its footing: failed (acquisition must settle at once); see
      :func:`umbra.modules.vision.tracker.settled`.
    """

    k_sigma: float = 3.0
    min_gray: float = 20.0
    dim_share: float = 0.4
    step_px: float = 2.0
    tension: float = 0.2
    window_radius_px: int = 2
    min_segment_px: float = 5.0
    max_segment_px: float = 12.0
    min_vertices: int = 8
    max_vertices: int = 400
    vertex_budget: int = 72
    seed_radius_px: float = 5.0
    seed_vertices: int = 12
    max_iterations: int = 300
    track_iterations: int = 12
    converge_px: float = 0.3
    adapt_rate: float = 0.1
    adapt_inset_px: float = 6.0
    edge_half_length_px: float = 4.0
    corner_turn_deg: float = 40.0
    side_fit_px: float = 1.0
    side_profiles: int = 32
    image_encoding: Encoding = "linear"
    min_edge_fraction: float = 0.5
    border_margin_px: float = 1.0
    min_chroma: float = 0.02
    max_unconverged_frames: int = 5

    @property
    def target_segment_px(self) -> float:
        """Segment length [px] the resampler aims at."""
        return 0.5 * (self.min_segment_px + self.max_segment_px)


@dataclass(frozen=True, eq=False)
class SnakeResult:
    """Outcome of evolving a snake: ``vertices`` (N x 2, px) the snake's own vertices,
    iterations run, whether it converged (last motion below ``converge_px``), the largest vertex
    motion of the last iteration [px], ``collapsed`` when the contour shrank to nothing;
    ``contour`` (M x 2, px) the measured outline (vertices on the fitted edge, corners put back;
    the vertices themselves when the edge fit is off or the snake collapsed), ``edge_fraction``
    the share of vertices with an edge under them, ``touches_border`` when the contour came
    within ``border_margin_px`` of the image border, and ``scale`` the pixel grid step it
    worked on (see :func:`grid_scale`)."""

    vertices: FloatArray
    iterations: int
    converged: bool
    last_motion_px: float
    collapsed: bool = False
    contour: FloatArray | None = None
    edge_fraction: float = 1.0
    touches_border: bool = False
    scale: int = 1

    @property
    def outline(self) -> FloatArray:
        """The measured outline when there is one, else the snake's vertices."""
        return self.vertices if self.contour is None else self.contour


def seed_point(center_uv: ArrayLike, params: SnakeParams) -> FloatArray:
    """Initial vertices for growing from a point: a small circle around ``center_uv``."""
    return circle(center_uv, params.seed_radius_px, params.seed_vertices)


def seed_region(polygon: ArrayLike, params: SnakeParams) -> FloatArray:
    """Initial vertices for collapsing onto a target from a region (rectangle or polygon)."""
    region = with_positive_area(as_polygon(polygon))
    return _resample(region, params)[0]


def outward_normals(vertices: FloatArray) -> FloatArray:
    """Unit outward normals at the vertices (from the neighbours' chord), for either order."""
    chord = following(vertices) - following(vertices, -1)
    normal = np.column_stack([chord[:, 1], -chord[:, 0]])
    if signed_area(vertices) < 0.0:
        normal = -normal
    length = np.hypot(normal[:, 0], normal[:, 1])
    return normal / np.maximum(length, 1e-12)[:, None]


def grid_scale(vertices: FloatArray, params: SnakeParams) -> int:
    """The pixel grid step σ (integer >= 1) the snake works on: 1 until the contour needs more
    than ``vertex_budget`` vertices at the target segment length, then the smallest step that
    keeps it within the budget (the snake then reads every σ-th pixel, with σ-times longer
    segments, steps and windows: the same work at any scale)."""
    perimeter = float(segment_lengths(vertices).sum())
    return max(1, int(np.ceil(perimeter / (params.target_segment_px * params.vertex_budget))))


def current_scale(vertices: FloatArray, params: SnakeParams) -> int:
    """The grid step σ a contour was last resampled for: its mean segment over the target."""
    mean = float(segment_lengths(vertices).mean())
    return max(1, round(mean / params.target_segment_px))


def pressure(
    image: NDArray[np.uint8],
    vertices: FloatArray,
    model: ColorModel,
    params: SnakeParams,
    scale: int = 1,
) -> FloatArray:
    """Pressure in [-1, 1] at each vertex: 2 x (weighted fraction of target pixels) - 1, over a
    window of ``2 r + 1`` grid cells of ``scale`` pixels (see
    :mod:`umbra.modules.vision.pressure`)."""
    return _field(image, model, params, scale)(vertices)


def _field(
    image: NDArray[np.uint8], model: ColorModel, params: SnakeParams, scale: int
) -> PressureField:
    return PressureField(
        image, model, params.k_sigma, params.min_gray, params.window_radius_px, scale
    )


def step(
    image: NDArray[np.uint8],
    vertices: FloatArray,
    model: ColorModel,
    params: SnakeParams,
    scale: int = 1,
) -> tuple[FloatArray, float]:
    """One iteration: move every vertex by pressure and tension; returns (vertices, max motion).

    The motion is measured before resampling; the vertices are kept inside the image.
    """
    return _step(_field(image, model, params, scale), vertices, params)


def _step(
    field: PressureField, vertices: FloatArray, params: SnakeParams
) -> tuple[FloatArray, float]:
    p = field(vertices)
    before = following(vertices, -1)
    after = following(vertices)
    chord = after - before
    # Shoelace sign: positive area means the outward normal is (chord_v, -chord_u).
    twice_area = np.dot(vertices[:, 0], after[:, 1]) - np.dot(after[:, 0], vertices[:, 1])
    length = np.hypot(chord[:, 0], chord[:, 1])
    push = (params.step_px * field.scale) * p / np.maximum(length, 1e-12)
    if twice_area < 0.0:
        push = -push
    motion = params.tension * (0.5 * (before + after) - vertices)
    motion[:, 0] += push * chord[:, 1]
    motion[:, 1] -= push * chord[:, 0]
    moved = vertices + motion
    np.clip(moved, 0.0, (field.width - 1.0, field.height - 1.0), out=moved)
    largest = float(np.sqrt(np.max(np.einsum("ij,ij->i", motion, motion))))
    return moved, largest


def needs_resampling(vertices: FloatArray, params: SnakeParams, scale: int = 1) -> bool:
    """True when, with fewer than the maximum number of vertices, a segment is longer than
    ``max_segment_px`` or, with more than the minimum, shorter than ``min_segment_px`` (both
    times the grid ``scale``). At ``max_vertices`` the segments are let grow (up to twice the
    mean segment, past which the vertices are spread evenly again)."""
    lengths = segment_lengths(vertices)
    count = vertices.shape[0]
    longest = float(lengths.max())
    if count >= params.max_vertices:
        too_long = longest > max(params.max_segment_px * scale, 2.0 * float(lengths.mean()))
    else:
        too_long = longest > params.max_segment_px * scale
    too_short = bool(lengths.min() < params.min_segment_px * scale)
    return too_long or (too_short and count > params.min_vertices)


def _resample(vertices: FloatArray, params: SnakeParams) -> tuple[FloatArray, int]:
    """Evenly spaced vertices at the target segment times the grid scale, and that scale."""
    scale = grid_scale(vertices, params)
    perimeter = float(segment_lengths(vertices).sum())
    count = round(perimeter / (params.target_segment_px * scale))
    count = int(np.clip(count, params.min_vertices, params.max_vertices))
    return resample_uniform(vertices, count), scale


def is_collapsed(vertices: FloatArray, params: SnakeParams, scale: int = 1) -> bool:
    """True when the contour has shrunk below one window: nothing is left to track."""
    extent = np.ptp(vertices, axis=0)
    return bool(extent.max() < (2.0 * params.window_radius_px + 1.0) * scale)


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
    scale = current_scale(current, params)
    if needs_resampling(current, params, scale):
        current, scale = _resample(current, params)
    field = _field(image, model, params, scale)  # reads the image in place
    motion = np.inf
    iterations = 0
    converged = False
    for iterations in range(1, budget + 1):
        current, motion = _step(field, current, params)
        if is_collapsed(current, params, scale):
            return SnakeResult(
                current, iterations, False, motion, collapsed=True, edge_fraction=0, scale=scale
            )
        if needs_resampling(current, params, scale):
            current, scale = _resample(current, params)
            if scale != field.scale:
                field = _field(image, model, params, scale)
            continue
        if motion < params.converge_px * scale:
            converged = True
            break
    contour, edge_fraction = measure_contour(image, current, model, params, scale)
    return SnakeResult(
        current,
        iterations,
        converged,
        motion,
        contour=contour,
        edge_fraction=edge_fraction,
        touches_border=touches_border(current, image.shape, params.border_margin_px),
        scale=scale,
    )


def touches_border(vertices: FloatArray, shape: tuple[int, ...], margin_px: float) -> bool:
    """True when a vertex lies within ``margin_px`` of the image's outer pixel centres."""
    height, width = shape[:2]
    low = vertices.min(axis=0)
    high = vertices.max(axis=0)
    return bool(
        low[0] <= margin_px
        or low[1] <= margin_px
        or high[0] >= width - 1.0 - margin_px
        or high[1] >= height - 1.0 - margin_px
    )


def measure_contour(
    image: NDArray[np.uint8],
    vertices: FloatArray,
    model: ColorModel,
    params: SnakeParams,
    scale: int = 1,
) -> tuple[FloatArray, float]:
    """The outline on the fitted colour edge, its sides fitted whole and measured again along
    their length (:mod:`umbra.modules.vision.side_profiles`) and its corners where they meet
    (:mod:`umbra.modules.vision.side_corners`; up to ``FINE_MEASURE_SCALE``), its other
    corners put back, and the share of points that found an edge (see
    :mod:`umbra.modules.vision.edge_fit`; corners met by ``CORNER_DEPTH_SEGMENTS`` and
    ``CORNER_REACH_SEGMENTS``). With the edge fit off, the vertices as they are and 1."""
    if params.edge_half_length_px <= 0.0:
        return vertices, 1.0
    if 1 < scale <= FINE_MEASURE_SCALE:
        perimeter = float(segment_lengths(vertices).sum())
        vertices = resample_uniform(vertices, max(round(perimeter / params.target_segment_px), 3))
    edge_params = EdgeFitParams(
        half_length_px=params.edge_half_length_px, encoding=params.image_encoding
    )
    fit = fit_edges(
        image,
        vertices,
        outward_normals(vertices),
        model,
        params.k_sigma,
        params.min_gray,
        edge_params,
        scale,
    )
    points, found = fit.vertices, fit.found
    if params.side_fit_px > 0.0 and scale <= FINE_MEASURE_SCALE:
        sides = fit_sides(points, found, params.side_fit_px)
        if sides is not None and params.side_profiles > 0:
            sides = remeasure_sides(
                sides,
                points,
                outward_normals(points),
                lambda at, normals: measure_near_edge(
                    image, at, normals, model, params.k_sigma, params.min_gray, edge_params
                ),
                params.side_profiles,
                params.side_fit_px,
            )
        if sides is not None:
            reach_px = CORNER_REACH_SEGMENTS * params.max_segment_px
            depth_px = CORNER_DEPTH_SEGMENTS * params.max_segment_px
            points, found, met = meet_corners(
                sides,
                found,
                reach_px,
                depth_px,
                lambda uv: is_target(
                    model, sample_bilinear(image, uv), params.k_sigma, params.min_gray
                ),
            )
            if met == 4:  # every corner is where its sides meet: none left to put back
                return points, fit.found_fraction
    contour = complete_corners(
        points, found, np.deg2rad(params.corner_turn_deg), params.max_segment_px * scale
    )
    return contour, fit.found_fraction


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
    """Pixels (K x 3 BGR) in 3 x 3 blocks ``adapt_inset_px`` inside the contour, one block per
    vertex (read by one fancy-indexing gather, never the whole image)."""
    height, width = image.shape[:2]
    inset = vertices - params.adapt_inset_px * outward_normals(vertices)
    centre = np.rint(inset).astype(np.intp)
    steps = np.arange(-1, 2)
    cols = np.clip(centre[:, 0:1] + steps, 0, width - 1)
    rows = np.clip(centre[:, 1:2] + steps, 0, height - 1)
    return image[rows[:, :, None], cols[:, None, :]].reshape(-1, image.shape[2])
