"""A patch's corners put where its fitted sides meet, and only where the snake merely rounded
them."""

from __future__ import annotations

import numpy as np

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
    rng = np.random.default_rng(12)
    points = rounded(QUAD, 5.0)
    cut = QUAD[2] + 0.15 * np.array([QUAD[1] - QUAD[2], QUAD[3] - QUAD[2]])
    near = np.hypot(*(points - QUAD[2]).T) < 0.15 * np.hypot(*(QUAD[1] - QUAD[2]))
    start = int(np.flatnonzero(near)[0])
    chord = np.linspace(cut[0], cut[1], 4)
    points = np.vstack([points[:start], chord, points[start:][~near[start:]]])
    points += rng.normal(0.0, 0.2, points.shape)
    found = np.ones(len(points), dtype=bool)
    fit = fit_sides(points, found, 1.0)
    assert fit is not None
    contour, _, met = meet_corners(fit, found, REACH_PX, DEPTH_PX)
    assert met == 3
    errors = corner_errors(contour, QUAD)
    assert errors[2] > 10.0
    assert np.delete(errors, 2).max() < 0.3
