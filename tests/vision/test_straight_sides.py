"""Each side of a quadrilateral contour measured with every edge point on it."""

from __future__ import annotations

import numpy as np

from umbra.modules.vision.straight_sides import straighten_sides

#: A patch under perspective (px, positive area in u right, v down).
QUAD = np.array([[100.0, 100.0], [228.0, 112.0], [220.0, 214.0], [96.0, 200.0]])


def on_sides(
    quad: np.ndarray, spacing_px: float = 8.5
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Evenly spaced points on the quadrilateral's sides (corners left out) and, for each, its
    unit outward normal and its side's index."""
    points, normals, sides = [], [], []
    for k in range(4):
        a, b = quad[k], quad[(k + 1) % 4]
        edge = b - a
        length = float(np.hypot(*edge))
        count = int(length // spacing_px)
        t = (np.arange(1, count) / count)[:, None]
        points.append(a + t * edge)
        normals.append(np.repeat([[edge[1] / length, -edge[0] / length]], count - 1, axis=0))
        sides.append(np.full(count - 1, k))
    return np.vstack(points), np.vstack(normals), np.concatenate(sides)


def distance_to_outline(points: np.ndarray, quad: np.ndarray) -> np.ndarray:
    best = np.full(len(points), np.inf)
    for k in range(4):
        a, b = quad[k], quad[(k + 1) % 4]
        edge = b - a
        t = np.clip((points - a) @ edge / (edge @ edge), 0.0, 1.0)
        best = np.minimum(best, np.hypot(*(points - a - t[:, None] * edge).T))
    return best


def test_noisy_edge_points_are_put_on_their_side() -> None:
    """Points 0.3 px (sd) off a perspective quadrilateral's sides, 11 to 15 a side: on the
    fitted sides their mean distance to the truth falls by a third or more (a quadratic through
    n points keeps about sqrt(3 / n) of their noise), in 20 draws."""
    truth, normals, _ = on_sides(QUAD)
    found = np.ones(len(truth), dtype=bool)
    before, after = [], []
    for seed in range(20):
        rng = np.random.default_rng(seed)
        noisy = truth + rng.normal(0.0, 0.3, len(truth))[:, None] * normals
        fitted = straighten_sides(noisy, found, 1.0)
        before.append(distance_to_outline(noisy, QUAD).mean())
        after.append(distance_to_outline(fitted, QUAD).mean())
    assert np.mean(after) < 0.67 * np.mean(before), (np.mean(before), np.mean(after))


def test_a_bowed_side_stays_on_its_curve() -> None:
    """A side bowed 1.5 px out at its middle (lens distortion) is a quadratic: its points stay
    where they are, to a hundredth of a pixel (the others to 0.05 px: the quadrilateral found
    on the bowed contour gives a side's fit a point or two of its neighbour's end)."""
    truth, normals, side = on_sides(QUAD)
    bow = np.zeros(len(truth))
    first = side == 0
    u = (truth[first, 0] - QUAD[0, 0]) / (QUAD[1, 0] - QUAD[0, 0])
    bow[first] = 6.0 * u * (1.0 - u)  # 1.5 px at the middle
    bowed = truth + bow[:, None] * normals
    fitted = straighten_sides(bowed, np.ones(len(truth), dtype=bool), 1.0)
    np.testing.assert_allclose(fitted[first], bowed[first], atol=0.01)
    np.testing.assert_allclose(fitted, bowed, atol=0.05)


def test_a_notch_and_unmeasured_points_stay_where_they_were() -> None:
    """A notch 3 px deep in one side is not the side: its points are left where the edge fit
    put them (the sanity checks still see it), while nearly all the other points are fitted (a
    side's end nearest a corner may count as its neighbour's and stand off it); points without
    a measured edge are left alone too."""
    truth, normals, _ = on_sides(QUAD)
    rng = np.random.default_rng(3)
    noisy = truth + rng.normal(0.0, 0.3, len(truth))[:, None] * normals
    notch = np.arange(4, 7)
    noisy[notch] -= 3.0 * normals[notch]
    found = np.ones(len(truth), dtype=bool)
    found[20] = False
    fitted = straighten_sides(noisy, found, 1.0)
    np.testing.assert_array_equal(fitted[notch], noisy[notch])
    np.testing.assert_array_equal(fitted[20], noisy[20])
    others = np.setdiff1d(np.arange(len(truth)), [*notch, 20])
    assert np.mean(np.any(fitted[others] != noisy[others], axis=1)) >= 0.85


def test_a_contour_that_is_no_view_of_a_rectangle_is_left_as_it_is() -> None:
    """A circle (its inscribed square is a view of a rectangle, but its quarters bow by a fifth
    of their chords) and a thin sliver (a side under half the one opposite) are returned
    unchanged."""
    angle = np.linspace(0.0, 2.0 * np.pi, 48, endpoint=False)
    rng = np.random.default_rng(5)
    circle = np.column_stack([160 + 60 * np.cos(angle), 120 + 60 * np.sin(angle)])
    circle += rng.normal(0.0, 0.3, circle.shape)
    found = np.ones(len(circle), dtype=bool)
    np.testing.assert_array_equal(straighten_sides(circle, found, 1.0), circle)
    sliver = np.array([[100.0, 100.0], [300.0, 100.0], [210.0, 140.0], [190.0, 140.0]])
    points, _, _ = on_sides(sliver, 6.0)
    points += rng.normal(0.0, 0.3, points.shape)
    found = np.ones(len(points), dtype=bool)
    np.testing.assert_array_equal(straighten_sides(points, found, 1.0), points)
