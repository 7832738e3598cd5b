"""Sanity checks: outer rectangle, inner ellipse, size, aspect ratio, rates of change."""

from __future__ import annotations

import numpy as np
import pytest

from umbra.connectors.tracking import SnakeCheck
from umbra.modules.vision.features import polygon_features
from umbra.modules.vision.polygon import rectangle, resample_uniform
from umbra.modules.vision.rectify import (
    apply_homography,
    is_rectangle_view,
    quadrilateral,
    rectifying_homography,
)
from umbra.modules.vision.sanity import (
    FAILED,
    TRACKING,
    SanityLimits,
    bounding_shapes,
    check_contour,
)
from umbra.modules.vision.snake_config import SnakeSettings

LIMITS = SanityLimits()


def rounded_rectangle(length: float, width: float, radius: float, angle: float) -> np.ndarray:
    """A rounded rectangle (what a snake on a rectangular patch looks like), 64 vertices."""
    t = np.linspace(0, 2 * np.pi, 400, endpoint=False)
    a, b = length / 2 - radius, width / 2 - radius
    core = np.column_stack([np.sign(np.cos(t)) * a, np.sign(np.sin(t)) * b])
    outline = core + radius * np.column_stack([np.cos(t), np.sin(t)])
    c, s = np.cos(angle), np.sin(angle)
    return resample_uniform(np.array([320.0, 240.0]) + outline @ np.array([[c, s], [-s, c]]), 64)


@pytest.mark.parametrize("angle", [0.0, 0.4, 1.2, -2.0])
def test_a_rounded_rectangle_passes(angle: float) -> None:
    result = check_contour(rounded_rectangle(160, 110, 6, angle), LIMITS)
    assert result.status == TRACKING, result.reason
    assert result.reason == ""
    assert result.offending.size == 0
    along, across = result.outer_rectangle.half_sizes
    assert along == pytest.approx(0.5 * 160 * 1.12, rel=0.02)
    assert across == pytest.approx(0.5 * 110 * 1.12, rel=0.02)
    assert result.inner_ellipse.half_sizes[0] == pytest.approx(0.5 * 160 * 0.85, rel=0.02)


def test_vertices_outside_the_rectangle_are_flagged() -> None:
    contour = rounded_rectangle(160, 110, 6, 0.3)
    bulge = contour.copy()
    bulge[10] += 30.0 * (bulge[10] - bulge.mean(axis=0)) / np.linalg.norm(bulge[10] - 320)
    result = check_contour(bulge, LIMITS)
    assert result.status == FAILED
    assert "outside the outer rectangle" in result.reason
    assert result.checks == (SnakeCheck.OUTSIDE_RECTANGLE,)
    assert 10 in result.offending


def test_vertices_inside_the_ellipse_are_flagged() -> None:
    contour = rounded_rectangle(160, 110, 6, 0.0)
    notch = contour.copy()
    centre = notch.mean(axis=0)
    notch[20] = centre + 0.4 * (notch[20] - centre)  # pulled far in, as by an occluder
    result = check_contour(notch, LIMITS)
    assert result.status == FAILED
    assert "inside the inner ellipse" in result.reason
    assert SnakeCheck.INSIDE_ELLIPSE in result.checks
    assert len(result.checks) == len(result.reasons)
    assert 20 in result.offending


def test_l_shape_and_triangle_fail_the_shape_checks() -> None:
    l_shape = np.array([[0, 0], [160, 0], [160, 50], [70, 50], [70, 110], [0, 110]], float)
    triangle = np.array([[0, 0], [160, 0], [0, 110]], float)
    for polygon in (l_shape, triangle):
        result = check_contour(resample_uniform(polygon + 100, 64), LIMITS)
        assert result.status == FAILED
        assert result.offending.size > 0


def test_size_and_aspect_bounds() -> None:
    small = check_contour(rectangle((50, 50), (10, 8)), LIMITS)
    assert "below the minimum" in small.reason
    assert SnakeCheck.AREA_BELOW_MIN in small.checks
    long_ = check_contour(resample_uniform(rectangle((300, 200), (400, 60)), 64), LIMITS)
    assert "aspect ratio 6.67 outside" in long_.reason
    patch_limits = SanityLimits(min_aspect=1.2, max_aspect=2.0)
    square = check_contour(resample_uniform(rectangle((300, 200), (100, 100)), 64), patch_limits)
    assert "aspect ratio 1.00 outside" in square.reason


def test_rates_of_change_against_the_previous_frame() -> None:
    before = rounded_rectangle(160, 110, 6, 0.0)
    previous = polygon_features(before)
    assert check_contour(before + np.array([8.0, -5.0]), LIMITS, previous).status == TRACKING
    jumped = check_contour(before + np.array([60.0, 0.0]), LIMITS, previous)
    assert "centroid jumped 60 px" in jumped.reason
    grown = check_contour(rounded_rectangle(200, 137, 7, 0.0), LIMITS, previous)
    assert "area changed +5" in grown.reason  # (200 x 137) / (160 x 110) = 1.56
    turned = check_contour(rounded_rectangle(160, 110, 6, np.deg2rad(30)), LIMITS, previous)
    assert "rotated 30 deg" in turned.reason
    stretched = check_contour(rounded_rectangle(200, 100, 6, 0.0), LIMITS, previous)
    assert "aspect ratio changed" in stretched.reason
    # The principal axis is defined modulo 180 degrees: a half turn is no rotation.
    half_turn = check_contour(rounded_rectangle(160, 110, 6, np.pi), LIMITS, previous)
    assert half_turn.status == TRACKING


def test_degenerate_contours_fail_cleanly() -> None:
    assert "vertices" in check_contour(np.zeros((2, 2)), LIMITS).reason
    flat = check_contour(np.array([[0, 0], [10, 0], [20, 0], [30, 0.0]]), LIMITS)
    assert flat.status == FAILED and "collapsed" in flat.reason
    with pytest.raises(ValueError, match="ellipse_scale"):
        SnakeSettings(ellipse_scale=1.5)  # the limits' rules are in the settings' declaration


def test_aspect_drift_from_the_acquired_contour() -> None:
    reference = polygon_features(rounded_rectangle(160, 110, 6, 0.0))
    closer = check_contour(rounded_rectangle(240, 165, 9, 0.5), LIMITS, reference=reference)
    assert closer.status == TRACKING  # approach and roll keep the aspect ratio
    leaked = check_contour(rounded_rectangle(230, 110, 6, 0.0), LIMITS, reference=reference)
    assert "aspect ratio +4" in leaked.reason and "from the acquired 1.45" in leaked.reason


# -- a patch seen obliquely -----------------------------------------------------------------------
#
# A generator of contours that is not the snake's: the outline of a w x h rectangle on a plane,
# drawn in the plane (with or without damage), seen by a pin-hole camera (focal length 600 px)
# with the plane tilted up to 55 deg about any in-plane axis and turned by any angle, from a
# distance at which its long side spans 120-300 px; 0.2 px of noise on every vertex.


def _outline(w: float, h: float, damage: str, rng: np.random.Generator) -> np.ndarray:
    """The patch's outline in its plane [m] (K x 2, counter-clockwise from (-w/2, -h/2)),
    ``damage`` applied to a random side or corner: a leak outwards or a bite inwards across the
    middle of a side (a third of its length, 20 % of the patch's other side deep), a corner cut
    off at 60 % of both sides, a quarter missing (an L), half missing along a diagonal."""
    corners = np.array([[-w, -h], [w, -h], [w, h], [-w, h]]) / 2.0
    turn = int(rng.integers(4))
    corners = np.roll(corners, -turn, axis=0)  # the damaged side runs from corners[0]
    a, b, c, d = corners
    side, across = b - a, d - a
    if damage in ("leak", "bite"):
        depth = (-0.2 if damage == "leak" else 0.2) * across
        points = [a, a + side / 3, a + side / 2 + depth, a + 2 * side / 3, b, c, d]
    elif damage == "cut corner":
        points = [a + 0.6 * side, b, c, d, a + 0.6 * across]
    elif damage == "L":
        points = [a + side / 2, b, c, d, a + across / 2, a + side / 2 + across / 2]
    elif damage == "triangle":
        points = [b, c, d]
    else:
        points = [a, b, c, d]
    polygon = np.array(points)
    return resample_uniform(polygon, 72)


def _seen(outline: np.ndarray, span_px: float, rng: np.random.Generator) -> np.ndarray:
    """``outline`` (K x 2 m, in its plane) as a camera sees it (K x 2 px)."""
    tilt = np.deg2rad(rng.uniform(0.0, 55.0))
    axis = rng.uniform(-np.pi, np.pi)
    k = np.array([np.cos(axis), np.sin(axis), 0.0])
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    R = np.eye(3) + np.sin(tilt) * K + (1 - np.cos(tilt)) * K @ K
    yaw = rng.uniform(-np.pi, np.pi)
    c, s = np.cos(yaw), np.sin(yaw)
    planar = outline @ np.array([[c, s], [-s, c]])
    extent = float(np.max(np.ptp(outline, axis=0)))
    depth = 600.0 * extent / span_px
    camera = np.column_stack([planar, np.zeros(len(planar))]) @ R.T + [0.0, 0.0, depth]
    uv = 600.0 * camera[:, :2] / camera[:, 2:3] + [320.0, 240.0]
    return uv + rng.normal(0.0, 0.2, uv.shape)


def _outside_moment_rectangle(contour: np.ndarray) -> bool:
    """Whether a vertex lies outside the outer rectangle of the contour's image moments."""
    rectangle, _ = bounding_shapes(polygon_features(contour), LIMITS)
    return bool(np.any(np.abs(rectangle.local(contour)) > np.asarray(rectangle.half_sizes)))


def test_a_patch_seen_obliquely_passes_and_its_damage_fails() -> None:
    """300 views of whole patches all pass (a third of them stand out of the rectangle of their
    image moments: the check is made on the patch seen head-on); each kind of damage fails on
    every one of 100 views."""
    rng = np.random.default_rng(4317)
    stand_out = 0
    for _ in range(300):
        w = 0.06
        outline = _outline(w, w * rng.uniform(0.4, 1.0), "none", rng)
        contour = _seen(outline, rng.uniform(120.0, 300.0), rng)
        result = check_contour(contour, LIMITS)
        assert result.status == TRACKING, result.reason
        stand_out += _outside_moment_rectangle(contour)
    assert stand_out > 100
    for damage in ("leak", "bite", "cut corner", "L", "triangle"):
        for _ in range(100):
            w = 0.06
            outline = _outline(w, w * rng.uniform(0.4, 1.0), damage, rng)
            contour = _seen(outline, rng.uniform(120.0, 300.0), rng)
            result = check_contour(contour, LIMITS)
            assert result.status == FAILED, damage
            assert {SnakeCheck.OUTSIDE_RECTANGLE, SnakeCheck.INSIDE_ELLIPSE} & set(result.checks)


def test_a_corner_cut_at_a_fifth_fails_whatever_vertex_lies_along_the_cut() -> None:
    """A corner cut off at a fifth of both sides, the outline sampled evenly (so that its
    vertices lie along the cut, one of them near its middle) and seen as in the test above:
    every one of 200 views fails. A quadrilateral with a corner halfway along the cut folded the
    cut's two ends into its sides, and they stood out of the outer rectangle by half as much
    (held-out photographs at 640 x 480: 2 of 200 such patches passed)."""
    rng = np.random.default_rng(5021)
    for _ in range(200):
        w = 0.06
        h = w * rng.uniform(0.4, 1.0)
        a, b, c, d = np.array([[-w, -h], [w, -h], [w, h], [-w, h]]) / 2.0
        cut = [a + 0.2 * (b - a), b, c, d, a + 0.2 * (d - a)]
        outline = resample_uniform(np.array(cut), int(rng.integers(40, 72)))
        contour = _seen(outline, rng.uniform(120.0, 300.0), rng)
        result = check_contour(contour, LIMITS)
        assert result.status == FAILED
        assert SnakeCheck.OUTSIDE_RECTANGLE in result.checks


def test_the_rectified_quadrilateral_is_the_patch_seen_head_on() -> None:
    """A rectangle under a known plane homography: its outline's quadrilateral is the image of
    its corners and maps back onto the unit square (to a hundredth of a side); a thin sliver
    and a near-triangle are no view of a rectangle."""
    H = np.array([[0.9, 0.25, 210.0], [-0.1, 0.7, 160.0], [4e-4, -6e-4, 1.0]])
    square = np.array([[0.0, 0.0], [200.0, 0.0], [200.0, 120.0], [0.0, 120.0]])
    corners = apply_homography(H, square)
    ends = zip(square, np.roll(square, -1, axis=0), strict=True)
    sides = [np.linspace(a, b, 15, endpoint=False) for a, b in ends]
    outline = apply_homography(H, np.concatenate(sides))
    quad = quadrilateral(outline)
    assert quad is not None
    assert np.allclose(np.sort(quad, axis=0), np.sort(corners, axis=0), atol=1e-3)
    rectified = apply_homography(rectifying_homography(outline), corners)
    unit = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    assert min(np.abs(np.roll(rectified, k, axis=0) - unit).max() for k in range(4)) < 0.01
    sliver = np.array([[0.0, 0.0], [200.0, 0.0], [400.0, 30.0], [200.0, 30.0]])
    near_triangle = np.array([[0.0, 0.0], [200.0, 0.0], [110.0, 150.0], [90.0, 150.0]])
    for shape in (sliver, near_triangle):
        assert not is_rectangle_view(shape)
        assert rectifying_homography(resample_uniform(shape, 60)) is None
