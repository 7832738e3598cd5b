"""A patch's corners where its fitted sides meet.

The snake's tension rounds a rectangle's corner, and the edge fit measures little there: a
vertex's normal at a corner crosses two edges at once, so its profile often holds no single
step (no edge found) or a step of the wrong side. On a patch 120 px across, a corner cut by 3 px
costs a tenth of a percent of its area and a corner's worth of IoU. When the contour follows a
view of a rectangle, each side is known whole (:mod:`umbra.modules.vision.straight_sides`), so
the corner is where two sides meet: the points between the last point put on one side's curve
and the first put on the next are replaced by the point where the least-squares lines through
the two sides' points cross. (Lines, not the sides' quadratics: a quadratic's end tangent,
carried a few pixels on to the corner, is noisy: with points 0.2 px off the sides, corners
0.68 px off against the lines' 0.20 px; lens distortion bows a side 120 px long by a few tenths
of a pixel, which moves its line's end by two thirds of that.)

Only a corner the snake merely rounded is put back: the meeting point lies ahead of both sides'
fitted points, those (and every point replaced) lie within ``reach_px`` of it (plus the share of
a side left out of its fit at each end), and the contour passes within ``depth_px`` of it or the
image reads as the patch all the way from the contour to it (the caller's test, clear of the
sides' blur). A corner cut off by an occluder is neither: its chord stands further off (cut at
15 % of a 120 px patch's sides, 13 px from the corner) and what lies beyond it is the occluder.
A bitten or bent corner leaves its sides' fitted points far from where they meet. Either is left
as measured, so the sanity checks still see it. (The snake's points lie a segment apart, and
blur and noise stop its gate short of a corner's tip: on the harsh held-out frames its contour
passes 6-12 px from corners the image shows whole.)

Pixels: u right, v down.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from umbra.modules.vision.straight_sides import END_SHARE, SideFit

FloatArray = NDArray[np.float64]
#: Whether the image reads as the patch at each point (K x 2 px): K booleans.
PatchTest = Callable[[FloatArray], NDArray[np.bool_]]
#: Samples of a corner's colour lie this far or more from its sides' lines, clear of their
#: edges' blur [px].
CLEAR_PX = 3.0


def meet_corners(
    fit: SideFit,
    found: NDArray[np.bool_],
    reach_px: float,
    depth_px: float,
    reads_as_patch: PatchTest | None = None,
) -> tuple[FloatArray, NDArray[np.bool_], int]:
    """The contour of ``fit`` (N x 2 px) with each corner between two fitted sides put where
    their lines meet (the points between their fitted points replaced by one), which of its
    points lie on a measured edge (``found``, the corners counting as measured), and how many
    corners were put there (0-4). ``reads_as_patch`` (points K x 2 px -> K booleans) lets a
    corner the contour passes further than ``depth_px`` from be put back where the image is the
    patch up to it; without it, only ``depth_px`` counts."""
    points = fit.points
    count = len(points)
    first, last = _end_points(fit)
    after = np.arange(4)
    before = (after - 1) % 4  # corner k: where side k - 1 ends and side k starts
    centre, direction = _side_lines(fit)
    a, ta, b, tb = centre[before], direction[before], centre[after], direction[after]
    det = ta[:, 1] * tb[:, 0] - ta[:, 0] * tb[:, 1]  # det [ta, -tb]
    norms = np.hypot(*ta.T) * np.hypot(*tb.T)
    gap = b - a
    t = (gap[:, 1] * tb[:, 0] - gap[:, 0] * tb[:, 1]) / np.where(det == 0.0, 1.0, det)
    corner = a + t[:, None] * ta  # the sides' lines meet here
    ok = fit.fitted[before] & fit.fitted[after] & (last[before] >= 0) & (first[after] >= 0)
    ok &= np.abs(det) > 1e-9 * norms
    end, start = last[before], first[after]
    # The corner lies ahead of the last fitted point of one side and behind the first of the
    # next, within reach of both.
    ok &= _along(fit, before, corner) > fit.along[end]
    ok &= _along(fit, after, corner) < fit.along[start]
    length = np.hypot(*fit.edge.T)
    reach = reach_px + END_SHARE * np.minimum(length[before], length[after])
    ok &= np.hypot(*(points[end] - corner).T) <= reach
    ok &= np.hypot(*(points[start] - corner).T) <= reach
    keep = np.ones(count, dtype=bool)
    inserted: dict[int, FloatArray] = {}
    for k in np.flatnonzero(ok):
        at, between = _between(int(end[k]), int(start[k]), count)
        # every point it replaces lies within reach of it too, and the contour passes near it
        if at in inserted or np.any(np.hypot(*(points[between] - corner[k]).T) > reach[k]):
            continue
        path = points[[int(end[k]), *between.tolist(), int(start[k])]]
        nearest = _nearest_on_path(corner[k], path)
        if np.hypot(*(nearest - corner[k])) > depth_px and not (
            reads_as_patch is not None
            and _patch_up_to(corner[k], nearest, (ta[k], tb[k]), reads_as_patch)
        ):
            continue
        keep[between] = False
        inserted[at] = corner[k]
    if not inserted:
        return points, found, 0
    after_index = sorted(inserted)
    tips = np.array([inserted[i] for i in after_index])
    slots = np.array(after_index, dtype=np.intp) + 1
    placed = np.insert(points, slots, tips, axis=0)
    measured = np.insert(found, slots, True)
    kept = np.insert(keep, slots, True)
    return placed[kept], measured[kept], len(inserted)


def _side_lines(fit: SideFit) -> tuple[FloatArray, FloatArray]:
    """Per side (4), the least-squares line through its points on its curve: their centroid
    (px) and its unit direction (along the side), from the points' second moments; the side
    itself where it has fewer than two."""
    one_hot = (fit.side == np.arange(4)[:, None]) & fit.on_curve  # (4, N)
    count = one_hot.sum(axis=1)
    weight = one_hot / np.maximum(count, 1)[:, None]
    centre = weight @ fit.points
    rel = fit.points[None, :, :] - centre[:, None, :]  # (4, N, 2)
    suu = np.einsum("kn,kn->k", weight, rel[..., 0] ** 2)
    svv = np.einsum("kn,kn->k", weight, rel[..., 1] ** 2)
    suv = np.einsum("kn,kn->k", weight, rel[..., 0] * rel[..., 1])
    angle = 0.5 * np.arctan2(2.0 * suv, suu - svv)
    direction = np.column_stack([np.cos(angle), np.sin(angle)])
    direction *= np.sign(np.einsum("kc,kc->k", direction, fit.edge))[:, None]
    few = count < 2
    centre[few] = fit.quad[few]
    direction[few] = fit.edge[few] / np.hypot(*fit.edge[few].T)[:, None]
    return centre, direction


def _end_points(fit: SideFit) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Per side (4), the index of its point on its curve nearest its start and nearest its end
    (-1 for a side without one)."""
    side = np.where(fit.on_curve, fit.side, 4)
    order = np.lexsort((fit.along, side))  # by side, then along it
    ranked = side[order]
    sides = np.arange(4)
    lo = np.searchsorted(ranked, sides, "left")
    hi = np.searchsorted(ranked, sides, "right")
    has = hi > lo
    last = len(order) - 1
    first = np.where(has, order[np.minimum(lo, last)], -1)
    end = np.where(has, order[np.clip(hi - 1, 0, last)], -1)
    return first, end


def _along(fit: SideFit, k: NDArray[np.intp], point: FloatArray) -> FloatArray:
    """How far each ``point`` (K x 2 px) lies along side ``k[i]``, in units of its length."""
    edge = fit.edge[k]
    return np.einsum("kc,kc->k", point - fit.quad[k], edge) / np.einsum("kc,kc->k", edge, edge)


def _between(last: int, first: int, count: int) -> tuple[int, NDArray[np.intp]]:
    """The contour's points strictly between indices ``last`` and ``first`` the short way
    round (a contour may run either way round its quadrilateral), and the index the corner goes
    after (the one of the two the short way starts from)."""
    forward, backward = (first - last) % count, (last - first) % count
    start, gap = (last, forward) if forward <= backward else (first, backward)
    return start, (start + np.arange(1, gap)) % count


def _nearest_on_path(point: FloatArray, path: FloatArray) -> FloatArray:
    """The point (2 px) of the polyline ``path`` (K x 2 px) nearest ``point`` (2 px)."""
    a, b = path[:-1], path[1:]
    edge = b - a
    length2 = np.maximum(np.einsum("kc,kc->k", edge, edge), 1e-12)
    t = np.clip(np.einsum("kc,kc->k", point - a, edge) / length2, 0.0, 1.0)
    on_path = a + t[:, None] * edge
    gap = on_path - point
    return on_path[int(np.argmin(np.einsum("kc,kc->k", gap, gap)))]


def _patch_up_to(
    corner: FloatArray,
    nearest: FloatArray,
    directions: tuple[FloatArray, FloatArray],
    reads_as_patch: PatchTest,
) -> bool:
    """Whether the image reads as the patch all the way from the contour's point ``nearest``
    (2 px) to where the sides meet at ``corner`` (2 px): sampled a pixel apart along that line
    from the contour on, wherever a sample lies ``CLEAR_PX`` or more from both sides' lines
    (unit ``directions``, 2 each). A corner the snake's tension rounded is the patch's colour
    up to its tip; one an occluder cut off is not (and the contour runs along the occluder's
    edge, where the colours mix). False where no sample fits."""
    gap = nearest - corner
    depth = float(np.hypot(*gap))
    if depth <= 0.0:
        return False
    toward = gap / depth
    # A point r along ``toward`` from the corner lies r |toward x d| from the line along d.
    sine = min(abs(float(toward[0] * d[1] - toward[1] * d[0])) for d in directions)
    if sine <= 0.0:
        return False
    first = CLEAR_PX / sine
    if first > depth:
        return False
    r = np.arange(depth, first - 1e-9, -1.0)
    return bool(np.all(reads_as_patch(corner + r[:, None] * toward)))
