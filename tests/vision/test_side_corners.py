"""A patch's corners put where its fitted sides meet, and only where the snake merely rounded
them."""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from umbra.modules.vision import photo_scene
from umbra.modules.vision.color import from_rgb, is_target
from umbra.modules.vision.edge_fit import sample_bilinear
from umbra.modules.vision.side_corners import meet_corners
from umbra.modules.vision.snake import CORNER_DEPTH_SEGMENTS, CORNER_REACH_SEGMENTS, SnakeParams
from umbra.modules.vision.straight_sides import fit_sides

#: The reach and depth the snake meets corners with (24 px and 6 px with the default segments).
REACH_PX = CORNER_REACH_SEGMENTS * SnakeParams().max_segment_px
DEPTH_PX = CORNER_DEPTH_SEGMENTS * SnakeParams().max_segment_px

#: A patch under perspective (px, positive area in u right, v down): corners of 80-100 deg.
QUAD = np.array([[100.0, 100.0], [228.0, 112.0], [220.0, 214.0], [96.0, 200.0]])


def rounded(quad: np.ndarray, cut_px: float, spacing_px: float = 8.5) -> np.ndarray:
    """Points every ``spacing_px`` along the quadrilateral's outline, with each corner cut by
    the chord between the points ``cut_px`` from it along its two sides (a snake's rounding:
    its points near a corner lie on neither side)."""
    points = []
    for k in range(4):
        a, b = quad[k], quad[(k + 1) % 4]
        edge = b - a
        length = float(np.hypot(*edge))
        count = int(length // spacing_px)
        t = np.arange(count) / count
        keep = (t * length >= cut_px) & ((1.0 - t) * length >= cut_px)
        points.append(a + t[keep, None] * edge)
        # the chord across corner k + 1 (ends cut_px from it on either side)
        c = quad[(k + 2) % 4] - b
        tip_in = b - cut_px * edge / length
        tip_out = b + cut_px * c / np.hypot(*c)
        points.append(np.array([tip_in, 0.5 * (tip_in + tip_out), tip_out]))
    return np.vstack(points)


def cut_at_corner_2(points: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``points`` (a contour of ``QUAD``) with corner 2 cut at 15 % of its sides (the chord an
    occluder's straight edge leaves, 13 px from the corner), every point then 0.2 px off at
    random; and the triangle cut off (3 x 2 px)."""
    tip = QUAD[2]
    ends = tip + 0.15 * np.array([QUAD[1] - tip, QUAD[3] - tip])
    near = np.hypot(*(points - tip).T) < 0.15 * np.hypot(*(QUAD[1] - tip))
    start = int(np.flatnonzero(near)[0])
    chord = np.linspace(ends[0], ends[1], 4)
    points = np.vstack([points[:start], chord, points[start:][~near[start:]]])
    return points + rng.normal(0.0, 0.2, points.shape), np.array([tip, ends[0], ends[1]])


def corner_errors(contour: np.ndarray, quad: np.ndarray) -> np.ndarray:
    """Distance (px) from each of the quadrilateral's corners to the nearest contour point."""
    gaps = contour[None, :, :] - quad[:, None, :]
    return np.sqrt(np.einsum("kni,kni->kn", gaps, gaps)).min(axis=1)


def test_corners_the_snake_rounded_are_put_where_the_sides_meet() -> None:
    """Corners cut by 3-7 px (a snake's rounding; its points 0.2 px off the sides at random):
    all four are put back, each within 0.3 px of the true corner, whichever way round the
    contour runs, and the points near the corners are replaced by them."""
    rng = np.random.default_rng(11)
    for cut in (3.0, 5.0, 7.0):
        points = rounded(QUAD, cut)
        points += rng.normal(0.0, 0.2, points.shape)
        for contour in (points, points[::-1].copy()):
            found = np.ones(len(contour), dtype=bool)
            fit = fit_sides(contour, found, 1.0)
            assert fit is not None
            before = corner_errors(contour, QUAD)
            met_contour, met_found, met = meet_corners(fit, found, REACH_PX, DEPTH_PX)
            assert met == 4
            assert len(met_found) == len(met_contour) < len(contour)
            assert before.min() > 0.5 * cut  # the corners really were cut
            assert corner_errors(met_contour, QUAD).max() < 0.3, (cut, met_contour)


def test_a_corner_cut_off_by_an_occluder_is_left_as_measured() -> None:
    """A corner cut at 15 % of its sides (an occluder's straight edge across it: its chord
    passes 13 px from the corner, beyond ``depth_px``) stays cut; the three others are put
    back."""
    points, _ = cut_at_corner_2(rounded(QUAD, 5.0), np.random.default_rng(12))
    found = np.ones(len(points), dtype=bool)
    fit = fit_sides(points, found, 1.0)
    assert fit is not None
    contour, _, met = meet_corners(fit, found, REACH_PX, DEPTH_PX)
    assert met == 3
    errors = corner_errors(contour, QUAD)
    assert errors[2] > 10.0
    assert np.delete(errors, 2).max() < 0.3


#: The patch's and the background's colours (BGR) in the pictures below.
PATCH_BGR = np.array([40.0, 60.0, 210.0])
BACKGROUND_BGR = np.array([150.0, 120.0, 60.0])


def picture(quad: np.ndarray, cut: np.ndarray | None = None) -> NDArray[np.uint8]:
    """A 320 x 260 picture of the patch ``quad`` drawn by area coverage (as a camera draws it),
    then blurred (sigma 1.2 px, a lens); ``cut`` (3 x 2 px) is a triangle an occluder of the
    background's colour covers."""
    shape = (260, 320)
    share = np.zeros(shape, np.float32)
    coverage, (u0, v0) = photo_scene.patch_coverage(quad, shape)
    share[v0 : v0 + coverage.shape[0], u0 : u0 + coverage.shape[1]] = coverage
    if cut is not None:
        covered, (u1, v1) = photo_scene.patch_coverage(cut, shape)
        window = share[v1 : v1 + covered.shape[0], u1 : u1 + covered.shape[1]]
        window *= 1.0 - covered
    image = BACKGROUND_BGR + share[..., None] * (PATCH_BGR - BACKGROUND_BGR)
    return np.rint(cv2.GaussianBlur(image, (0, 0), 1.2)).astype(np.uint8)


def patch_test(image: NDArray[np.uint8]):
    """Whether ``image`` reads as the patch at points (K x 2 px), as the snake asks it."""
    model, gate = from_rgb(PATCH_BGR[::-1]), SnakeParams()
    return lambda uv: is_target(model, sample_bilinear(image, uv), gate.k_sigma, gate.min_gray)


def test_a_deeply_rounded_corner_is_put_back_where_the_image_is_the_patch_to_its_tip() -> None:
    """Corners rounded by 12 px (the contour passes 8-9 px from them, beyond ``depth_px``: a
    snake's points 17 px apart on a blurred, noisy patch): without a look at the image none is
    put back; where the picture reads as the patch up to each corner, all four are, within
    0.6 px (the sides' lines, through points 0.2 px off them, carried 12 px on)."""
    rng = np.random.default_rng(13)
    points = rounded(QUAD, 12.0)
    points += rng.normal(0.0, 0.2, points.shape)
    found = np.ones(len(points), dtype=bool)
    fit = fit_sides(points, found, 1.0)
    assert fit is not None
    assert meet_corners(fit, found, REACH_PX, DEPTH_PX)[2] == 0
    contour, _, met = meet_corners(fit, found, REACH_PX, DEPTH_PX, patch_test(picture(QUAD)))
    assert met == 4
    assert corner_errors(contour, QUAD).max() < 0.6


def test_a_corner_an_occluder_cut_is_left_cut_whatever_the_image_shows_elsewhere() -> None:
    """The corner cut at 15 % of its sides, an occluder of the background's colour over it in
    the picture and the contour along the occluder's edge: the image does not read as the
    patch between the contour and where the sides meet, so it stays cut, while the three
    corners rounded by 12 px are put back (within 0.6 px)."""
    points, occluder = cut_at_corner_2(rounded(QUAD, 12.0), np.random.default_rng(14))
    found = np.ones(len(points), dtype=bool)
    fit = fit_sides(points, found, 1.0)
    assert fit is not None
    contour, _, met = meet_corners(
        fit, found, REACH_PX, DEPTH_PX, patch_test(picture(QUAD, occluder))
    )
    assert met == 3
    errors = corner_errors(contour, QUAD)
    assert errors[2] > 10.0
    assert np.delete(errors, 2).max() < 0.6
