"""Sub-pixel edges: the edge profile fitted along each normal puts a vertex on the colour edge to
a tenth of a pixel, whatever the blur, and the measured outline of a rendered patch carries no
systematic area bias (the snake's own vertices sit ~0.8 px inside)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from umbra.modules.vision import color
from umbra.modules.vision import snake as sn
from umbra.modules.vision.edge_fit import complete_corners, fit_edges, sample_bilinear
from umbra.modules.vision.lighting import Lighting
from umbra.modules.vision.metrics import polygon_iou
from umbra.modules.vision.polygon import circle, resample_uniform, signed_area
from umbra.modules.vision.scene import Scene, pose

from .conftest import T_WORLD_CAMERA

PATCH_BGR = np.array([60, 170, 30], dtype=np.float64)
BACKGROUND_BGR = np.array([150, 180, 205], dtype=np.float64)
MODEL = color.from_rgb((30, 170, 60), 8.0)


def half_plane_image(
    offset_px: float,
    angle_rad: float,
    blur_sigma_px: float,
    noise: float,
    rng,
    patch_bgr: np.ndarray = PATCH_BGR,
    background_bgr: np.ndarray = BACKGROUND_BGR,
    encode=None,
) -> tuple[np.ndarray, np.ndarray, float]:
    """A 200 x 200 image: patch colour where n . (x - c) < offset, n at ``angle_rad``; area
    sampled exactly (16x supersampling), then Gaussian blur (as a lens blurs, before the sensor
    clips) and noise, all on light; then ``encode`` (light 0..255 to codes 0..255; None: codes
    are light). Returns the image, the unit normal n and the offset c . n + offset of the
    edge line n . x = that value."""
    size, fine = 200, 16
    normal = np.array([np.cos(angle_rad), np.sin(angle_rad)])
    centre = np.array([100.0, 100.0])
    grid = (np.arange(size * fine) + 0.5) / fine - 0.5
    uu, vv = np.meshgrid(grid, grid)
    inside = (uu - centre[0]) * normal[0] + (vv - centre[1]) * normal[1] < offset_px
    coverage = inside.reshape(size, fine, size, fine).mean(axis=(1, 3))[:, :, None]
    image = coverage * patch_bgr + (1.0 - coverage) * background_bgr
    if blur_sigma_px > 0:
        image = cv2.GaussianBlur(image, (0, 0), blur_sigma_px)
    image = image + rng.normal(0.0, noise, image.shape)
    if encode is not None:
        image = encode(np.clip(image, 0.0, 255.0))
    edge = float(centre @ normal + offset_px)
    return np.clip(np.rint(image), 0, 255).astype(np.uint8), normal, edge


@pytest.mark.parametrize("noise", [0.0, 4.0])
@pytest.mark.parametrize("blur_sigma_px", [0.0, 0.5, 0.9])
@pytest.mark.parametrize("offset_px", [0.0, 0.3, -0.45])
def test_vertices_settle_on_a_straight_edge_to_a_tenth_of_a_pixel(
    offset_px: float, blur_sigma_px: float, noise: float
) -> None:
    rng = np.random.default_rng(3)
    angle = 0.37
    image, normal, edge = half_plane_image(offset_px, angle, blur_sigma_px, noise, rng)
    # 40 vertices along the edge, each started up to 1 px off it on either side (a converged
    # snake rests within a pixel of the edge; the profile of +-4 px then holds the blurred edge).
    along = np.array([-normal[1], normal[0]])
    t = np.linspace(-60.0, 60.0, 40)
    start_offsets = rng.uniform(-1.0, 1.0, t.size)
    on_edge = np.array([100.0, 100.0]) + offset_px * normal + t[:, None] * along
    vertices = on_edge + start_offsets[:, None] * normal
    normals = np.repeat(normal[None, :], t.size, axis=0)
    fit = fit_edges(image, vertices, normals, MODEL, 3.0, 20.0)
    assert fit.found.all()
    residual = fit.vertices @ normal - edge
    assert np.abs(start_offsets).mean() > 0.4  # they really started off the edge
    assert abs(residual.mean()) < 0.03  # no bias
    if noise == 0.0:
        assert np.abs(residual).max() < 0.05
    else:  # 4 gray levels of noise against a contrast of ~200: ~0.06 px per vertex (RMS)
        assert np.sqrt(np.mean(residual**2)) < 0.08
        assert np.abs(residual).max() < 0.2


def test_no_edge_is_found_on_a_uniform_image() -> None:
    image = np.full((100, 100, 3), (60, 170, 30), dtype=np.uint8)
    vertices = circle((50, 50), 20, 16)
    fit = fit_edges(image, vertices, sn.outward_normals(vertices), MODEL, 3.0, 20.0)
    assert not fit.found.any()
    assert fit.found_fraction == 0.0
    np.testing.assert_array_equal(fit.vertices, vertices)


def test_bilinear_sampling_is_exact_to_the_gray_level() -> None:
    rng = np.random.default_rng(5)
    image = rng.integers(0, 256, (30, 40, 3), dtype=np.uint8)
    points = rng.uniform([0, 0], [38.99, 28.99], (50, 7, 2))
    ours = sample_bilinear(image, points)
    assert ours.shape == (50, 7, 3)
    u0, v0 = np.floor(points[..., 0]).astype(int), np.floor(points[..., 1]).astype(int)
    fu, fv = (points[..., 0] - u0)[..., None], (points[..., 1] - v0)[..., None]
    pixels = image.astype(float)
    exact = (1 - fv) * ((1 - fu) * pixels[v0, u0] + fu * pixels[v0, u0 + 1]) + fv * (
        (1 - fu) * pixels[v0 + 1, u0] + fu * pixels[v0 + 1, u0 + 1]
    )
    error = ours - exact
    assert np.abs(error).max() <= 1.0  # rounded to the gray level (positions to 1/32 px)
    assert abs(error.mean()) < 0.1  # and without bias
    # Points outside read the border pixel.
    border = sample_bilinear(image, np.array([[[-5.0, 3.0], [60.0, 100.0]]]))
    np.testing.assert_array_equal(border[0], image[[3, 29], [0, 39]].astype(np.float32))


def test_corners_of_an_evenly_sampled_square_are_put_back() -> None:
    square = np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 60.0], [0.0, 60.0]])
    # Evenly spaced vertices, shifted so that none falls on a corner, then the corners cut.
    dense = resample_uniform(np.roll(resample_uniform(square, 320), -3, axis=0), 320)
    cut = dense[::10]
    found = np.ones(len(cut), dtype=bool)
    completed = complete_corners(cut, found, np.deg2rad(40.0), 12.0)
    assert len(completed) == len(cut) + 4
    assert abs(signed_area(cut)) < 6000.0 - 10.0  # the cut polygon lost its corners
    assert abs(signed_area(completed)) == pytest.approx(6000.0, abs=1e-6)
    for corner in square:
        assert np.min(np.hypot(*(completed - corner).T)) < 1e-6


def test_a_smooth_contour_keeps_its_vertices() -> None:
    ring = circle((50.0, 50.0), 30.0, 24)
    completed = complete_corners(ring, np.ones(24, dtype=bool), np.deg2rad(40.0), 12.0)
    np.testing.assert_array_equal(completed, ring)


@pytest.mark.parametrize("gain", [0.5, 1.0, 1.5])
def test_measured_outline_of_a_rendered_patch_has_no_area_bias(renderer, gain: float) -> None:
    """Distorted lens, photo background, motion blur 2 px, noise 6 gray levels: the snake's own
    vertices sit inside the edge (area 0.5-3 % short), the measured outline's area is within
    0.2 % of the truth polygon's on average and 0.4 % on every frame."""
    rng = np.random.default_rng(17)
    biases, raw_biases = [], []
    for k in range(4):
        scene = Scene(
            T_world_patch=pose((0.004 * k - 0.006, 0.003, 0.03), 0.4 * k + 0.2),
            background="photo",
        )
        lighting = Lighting(gain=gain, noise_sigma=6.0, blur_length_px=2.0, blur_angle_rad=0.7 * k)
        frame = renderer.render(scene, T_WORLD_CAMERA, lighting, rng)
        seed = frame.patch_polygon.mean(axis=0)
        params = sn.SnakeParams()
        model = color.fit(sn.seed_samples(frame.image, seed, params.seed_radius_px))
        result = sn.acquire(frame.image, seed, model, params)
        truth = abs(signed_area(frame.patch_polygon))
        biases.append(abs(signed_area(result.contour)) / truth - 1.0)
        raw_biases.append(abs(signed_area(result.vertices)) / truth - 1.0)
        assert result.edge_fraction > 0.9
        assert polygon_iou(result.contour, frame.patch_polygon, (480, 640)) > 0.99
    assert np.mean(raw_biases) < -0.005
    assert abs(np.mean(biases)) < 0.002
    assert np.max(np.abs(biases)) < 0.004


@pytest.mark.parametrize("blur_sigma_px", [0.6, 1.2])
def test_an_edge_whose_patch_channel_clips_is_found_where_it_is(blur_sigma_px: float) -> None:
    """A red patch at a lighting gain of 1.6 (its red would be 320: the sensor clips it at 255)
    on a dark background, blurred before the clip as a lens blurs: the clipped red channel
    carries most of the edge's contrast and, left clipped, half its step lies 0.2-0.45 px
    outside the edge (0.20 px at a blur of 0.6 px, 0.38 px at 1.2). With the clipped samples put
    back on the patch's colour ray the edge is found to 0.1 px (a sample mixed with a little
    background is put back as if it were all patch: -0.08 px at 0.6)."""
    size, fine, offset = 200, 8, 0.3
    grid = (np.arange(size * fine) + 0.5) / fine - 0.5
    uu, _ = np.meshgrid(grid, grid)
    coverage = (uu < 100.0 + offset).reshape(size, fine, size, fine).mean(axis=(1, 3))
    patch, background = np.array([64.0, 64.0, 320.0]), np.array([20.0, 24.0, 22.0])
    image = coverage[:, :, None] * patch + (1.0 - coverage[:, :, None]) * background
    image = cv2.GaussianBlur(image, (0, 0), blur_sigma_px)
    image = np.clip(np.rint(image), 0, 255).astype(np.uint8)
    model = color.from_rgb((200, 40, 40), 4.0)
    v = np.linspace(40.0, 160.0, 30)
    vertices = np.column_stack([np.full(v.size, 99.0), v])
    normals = np.repeat([[1.0, 0.0]], v.size, axis=0)
    fit = fit_edges(image, vertices, normals, model, 3.0, 20.0)
    assert fit.found.all()
    residual = fit.vertices[:, 0] - (100.0 + offset)
    assert np.abs(residual).max() < 0.1, residual


def _vertical_edge(
    patch_bgr: np.ndarray, background_bgr: np.ndarray, blur_sigma_px: float, edge_px: float
) -> np.ndarray:
    """A 200 x 200 frame: the patch left of the vertical line u = ``edge_px``, area-sampled
    (8x), Gaussian blur as a lens blurs (before the sensor clips), then clipped to 8 bits."""
    size, fine = 200, 8
    grid = (np.arange(size * fine) + 0.5) / fine - 0.5
    uu, _ = np.meshgrid(grid, grid)
    coverage = (uu < edge_px).reshape(size, fine, size, fine).mean(axis=(1, 3))[:, :, None]
    image = coverage * patch_bgr + (1.0 - coverage) * background_bgr
    image = cv2.GaussianBlur(image, (0, 0), blur_sigma_px)
    return np.clip(np.rint(image), 0, 255).astype(np.uint8)


@pytest.mark.parametrize(
    ("wall", "blur_sigma_px", "tolerance_px"),
    [(280.0, 1.0, 0.1), (280.0, 1.4, 0.1), (300.0, 1.4, 0.15)],
)
def test_an_edge_against_a_white_background_that_clips_is_found_where_it_is(
    wall: float, blur_sigma_px: float, tolerance_px: float
) -> None:
    """A green patch against a white wall at a gain that clips it (280-300 in every channel:
    the sensor reads 255), blurred before the clip: every channel with contrast is clipped on
    the background's side, so the half step between the ends lies 0.27-0.49 px inside the edge.
    The profile's steepest point, channel by channel where it is not clipped, is the edge: found
    to 0.1-0.15 px."""
    edge_px = 100.3
    patch = np.array([70.0, 190.0, 40.0])
    image = _vertical_edge(patch, np.full(3, wall), blur_sigma_px, edge_px)
    fit = _fit_vertical(image, color.from_rgb(patch[::-1], 6.0))
    assert fit.found.all()
    residual = fit.vertices[:, 0] - edge_px
    assert np.abs(residual).max() < tolerance_px, residual


@pytest.mark.parametrize(
    "patch_bgr", [(70.0, 190.0, 40.0), (220.0, 120.0, 60.0), (50.0, 60.0, 200.0)]
)
def test_an_edge_whose_steepest_point_the_clip_hides_is_found_past_the_last_difference_seen(
    patch_bgr: tuple[float, float, float],
) -> None:
    """A wall that clips at about 1.14x the sensor's top (290, 281, 296), edges at any angle
    and a blur of 0.6-1.3 px: the clip often hides the difference just past the steepest one
    seen, so the peak was left unplaced and the half step between the clipped ends measured
    the edge: 0.20 and 0.24 px inside it on average (green, blue). Placed by a parabola through
    the last three differences seen, it is found 0.05-0.09 px inside it."""
    patch = np.array(patch_bgr)
    model = color.from_rgb(patch[::-1], 6.0)
    means = []
    for seed in range(8):
        rng = np.random.default_rng(seed)
        angle, offset_px = rng.uniform(0.0, 2.0 * np.pi), rng.uniform(-0.5, 0.5)
        image, normal, edge = half_plane_image(
            offset_px,
            angle,
            rng.uniform(0.6, 1.3),
            1.5,
            rng,
            patch_bgr=patch,
            background_bgr=np.array([290.0, 281.0, 296.0]),
        )
        residual = _fit_across(image, normal, offset_px, edge, model, 30, (-1.5, 0.5), rng)
        means.append(residual.mean())
    assert abs(np.mean(means)) < 0.15, np.mean(means)


def test_an_edge_clipped_before_its_steepest_point_is_still_measured() -> None:
    """A brighter wall (330) behind a sharper edge (0.8 px): the profile clips at its steepest
    point. The edge is still measured rather than not found (a whole contour against such a
    wall would fail as featureless): by the half step between the ends 0.46 px inside it, by a
    parabola through the last three differences seen before the clip 0.33 px inside it."""
    edge_px = 100.3
    patch = np.array([70.0, 190.0, 40.0])
    image = _vertical_edge(patch, np.full(3, 330.0), 0.8, edge_px)
    fit = _fit_vertical(image, color.from_rgb(patch[::-1], 6.0))
    assert fit.found.all()
    assert np.abs(fit.vertices[:, 0] - edge_px).max() < 0.4


def _fit_vertical(image: np.ndarray, model: color.ColorModel):
    """The edge fit of 30 vertices at u = 99 (1.3 px inside the edge), normals along +u."""
    v = np.linspace(40.0, 160.0, 30)
    vertices = np.column_stack([np.full(v.size, 99.0), v])
    normals = np.repeat([[1.0, 0.0]], v.size, axis=0)
    return fit_edges(image, vertices, normals, model, 3.0, 20.0)


def _edges_of_half_planes(damage) -> tuple[float, float]:
    """Twelve straight edges (random angle and offset, 0.9 px blur, 2 gray levels of noise),
    each ``damage(image, rng)``-ed, fitted by 40 vertices started up to 1 px off: the largest
    mean residual of an edge and the mean RMS residual [px]."""
    biases, spreads = [], []
    for seed in range(12):
        rng = np.random.default_rng(seed)
        angle, offset_px = rng.uniform(0.0, np.pi), rng.uniform(-0.5, 0.5)
        image, normal, edge = half_plane_image(offset_px, angle, 0.9, 2.0, rng)
        image = damage(image, rng)
        residual = _fit_across(image, normal, offset_px, edge, MODEL, 40, (-1.0, 1.0), rng)
        biases.append(abs(residual.mean()))
        spreads.append(np.sqrt(np.mean(residual**2)))
    return max(biases), float(np.mean(spreads))


def _fit_across(
    image: np.ndarray,
    normal: np.ndarray,
    offset_px: float,
    edge: float,
    model: color.ColorModel,
    count: int,
    start_px: tuple[float, float],
    rng,
) -> np.ndarray:
    """Residuals [px, along ``normal``] of the vertices that found the straight edge
    ``normal . x = edge`` of a :func:`half_plane_image`: ``count`` vertices over 120 px of it,
    each started off it by a uniform draw within ``start_px``; at least 85 % find it."""
    along = np.array([-normal[1], normal[0]])
    t = np.linspace(-60.0, 60.0, count)
    start = rng.uniform(*start_px, t.size)
    on_edge = np.array([100.0, 100.0]) + offset_px * normal + t[:, None] * along
    vertices = on_edge + start[:, None] * normal
    fit = fit_edges(image, vertices, np.repeat(normal[None, :], t.size, 0), model, 3.0, 20.0)
    assert fit.found.mean() >= 0.85
    return (fit.vertices @ normal - edge)[fit.found]


def test_a_channel_the_background_textures_counts_less() -> None:
    """Blue carries a texture of 20 gray levels (a grain 1.5 px across) on both sides of the
    edge. Weighing the channels by their step alone, blue's texture moved the edges 0.14 px
    RMS (0.09 px on average on one edge); weighed by the colours' spread measured at the
    profiles' ends, the clean channels carry the edge: 0.05 px RMS."""

    def textured(image: np.ndarray, rng) -> np.ndarray:
        grain = cv2.GaussianBlur(rng.normal(0.0, 1.0, image.shape[:2]), (0, 0), 1.5)
        out = image.astype(np.float64)
        out[..., 0] += 20.0 * grain / grain.std()
        return np.clip(np.rint(out), 0, 255).astype(np.uint8)

    worst_bias, rms = _edges_of_half_planes(textured)
    assert worst_bias < 0.05 and rms < 0.07, (worst_bias, rms)


def test_an_edge_through_jpeg_at_quality_70_is_found_to_a_tenth_of_a_pixel() -> None:
    """JPEG keeps colour at half resolution and quantises it coarsely: the colour channels'
    steps smear and ring. Weighted by their step alone the edges were 0.10 px RMS off; by the
    colours' spread, 0.07 px."""

    def jpeg(image: np.ndarray, _rng) -> np.ndarray:
        _, encoded = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 70])
        return cv2.imdecode(encoded, cv2.IMREAD_COLOR)

    worst_bias, rms = _edges_of_half_planes(jpeg)
    assert worst_bias < 0.04 and rms < 0.085, (worst_bias, rms)
