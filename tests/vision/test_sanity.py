"""Sanity checks: outer rectangle, inner ellipse, size, aspect ratio, rates of change."""

from __future__ import annotations

import numpy as np
import pytest

from umbra.connectors.tracking import SnakeCheck
from umbra.modules.vision.features import polygon_features
from umbra.modules.vision.polygon import rectangle, resample_uniform
from umbra.modules.vision.sanity import FAILED, TRACKING, SanityLimits, check_contour
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
