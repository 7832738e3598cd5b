"""The sides of a patch seen as a quadrilateral, measured along their whole length.

Each edge point the edge fit measures (:mod:`umbra.modules.vision.edge_fit`) carries its own
noise: sensor noise and JPEG's 8 x 8 blocks move it by a few tenths of a pixel, which on a patch
120 px across is a percent of its area. A patch's side is one curve, though: a straight line in
a pinhole view, slightly bowed by lens distortion. When the contour follows a quadrilateral that
a camera can see a rectangle as (:func:`umbra.modules.vision.rectify.quadrilateral`), the edge
points on each side are put on the quadratic fitted to them all (their offsets across the side
as a quadratic of the position along it, in least squares), so each side is measured with every
point on it.

Only points that lie within ``max_offset_px`` of that curve take part and are moved (the fit is
repeated without the others): a notch, a bulge, a rounded corner or a speck of texture stands
off the curve and stays where the edge fit put it, so the contour still shows damage to the
sanity checks. The points within ``END_SHARE`` of a side's ends are left as measured too
(which side they belong to is ambiguous): :func:`fit_sides` says which points lie on which
side's curve, and :mod:`umbra.modules.vision.side_corners` puts the corners where the sides
meet. A side is fitted only when at least ``min_points`` points, and most of those it
measured, lie on a curve that bows by at most ``_MAX_BOW`` of its length (a circle's quarter
bows by 21 %); a contour that is not a view of a rectangle is returned as it is.

Pixels: u right, v down.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from umbra.modules.vision.rectify import is_rectangle_view, quadrilateral

FloatArray = NDArray[np.float64]

#: The passes of the fit that drops the points off the curve, each keeping those within this
#: many times ``max_offset_px`` of the last pass's curve (a first fit through every point is
#: pulled by a notch: the widest reach first); the last pass's points are moved.
_REACH = (4.0, 2.0, 1.0)
#: Powers of the position along a side (the moments of a quadratic fit), the sides' indices
#: (a column), and the 3 x 3 normal equations' indices into the moments.
_POWERS = np.arange(5)
_SIDES = np.arange(4)[:, None]
_SQUARE = np.add.outer(np.arange(3), np.arange(3))

#: The share of a side's length at either end whose points are left as measured.
END_SHARE = 0.05

#: Largest bow of a side's fitted curve at its middle, in units of its length: lens distortion
#: bows a patch's side by a percent or two; a circle's quarter by 21 %.
_MAX_BOW = 0.05


@dataclass(frozen=True, eq=False)
class SideFit:
    """The four sides of a contour that follows a view of a rectangle, each fitted whole.

    Side k runs from ``quad[k]`` along ``edge[k]`` (px); ``fitted[k]``: its points lie on its
    curve (see :func:`straighten_sides`). Per contour point: ``side`` its side's index,
    ``along`` how far along it it lies (in units of its length, 0 at ``quad[k]``), and
    ``on_curve`` whether it was put on its side's curve (``points`` has it there). Per side:
    ``curve`` (4 x 3) its curve's offset across it as a quadratic of ``along`` (see
    :func:`side_curves`), measured along the unit vector ``across`` (4 x 2) [px]."""

    points: FloatArray
    quad: FloatArray
    edge: FloatArray
    fitted: NDArray[np.bool_]
    side: NDArray[np.intp]
    along: FloatArray
    on_curve: NDArray[np.bool_]
    curve: FloatArray
    across: FloatArray


def straighten_sides(
    points: FloatArray,
    found: NDArray[np.bool_],
    max_offset_px: float,
    min_points: int = 6,
) -> FloatArray:
    """``points`` (N x 2 px, a closed contour's edge points) with those on each side of the
    quadrilateral it follows put on that side's fitted quadratic; only points where an edge was
    measured (``found``) take part. Unchanged when the contour is not a view of a rectangle."""
    fit = fit_sides(points, found, max_offset_px, min_points)
    return points if fit is None else fit.points


def fit_sides(
    points: FloatArray,
    found: NDArray[np.bool_],
    max_offset_px: float,
    min_points: int = 6,
) -> SideFit | None:
    """The sides of the quadrilateral ``points`` (N x 2 px) follows, fitted (see
    :func:`straighten_sides`); None when the contour is not a view of a rectangle. The four
    sides are fitted together (their moments in one product, one batched 3 x 3 solve per pass):
    0.25-0.35 ms a frame for 60 points, a third of it finding the quadrilateral."""
    quad = quadrilateral(points)
    if quad is None or not is_rectangle_view(quad):
        return None
    edge = quad[[1, 2, 3, 0]] - quad
    side = _nearest_side(points, quad, edge)
    length = np.hypot(edge[:, 0], edge[:, 1])
    if length.min() <= 1e-9:
        return None
    direction = edge / length[:, None]
    across = direction[:, ::-1] * [1.0, -1.0]
    # Each point's side frame: along (in units of the side's length) and across [px].
    frame = np.stack([direction / length[:, None], across], axis=1)
    rel = points - quad[side]
    s, d = np.einsum("nkc,nc->kn", frame[side], rel)
    # Points near a side's ends are left out: which side a point there belongs to is ambiguous,
    # and the corners are put back by lines through the sides' fitted points.
    use = found & (s >= END_SHARE) & (s <= 1.0 - END_SHARE)
    coef, keep = side_curves(s, d, side, use, max_offset_px, min_points)
    residual = d - on_curve(coef, side, s)
    one_hot = side == _SIDES  # (4, N)
    kept = np.count_nonzero(one_hot & keep, axis=1)
    # A side is a side when enough of its points lie on its curve, most of those it measured,
    # and that curve is nearly straight (a quarter of a circle bows by 21 % of its chord).
    sides = (kept >= min_points) & (kept >= 0.5 * np.count_nonzero(one_hot & use, axis=1))
    sides &= 0.25 * np.abs(coef[:, 2]) <= _MAX_BOW * length
    move = keep & sides[side]
    out = points.copy()
    out[move] -= residual[move, None] * across[side[move]]
    return SideFit(out, quad, edge, sides, side, s, move, coef, across)


def side_curves(
    along: FloatArray,
    across: FloatArray,
    side: NDArray[np.intp],
    use: NDArray[np.bool_],
    max_offset_px: float,
    min_points: int,
    bow_z: float = 0.0,
    shared_noise: float = 1.0,
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Each side's curve: the quadratic ``across = c0 + c1 s + c2 s²`` [px] of the position
    ``along`` it (s, in units of its length) fitted in least squares to the points (N) of that
    ``side`` (0-3) with ``use``, in passes that each keep those within ``_REACH`` times
    ``max_offset_px`` of the last pass's curve. Returns the coefficients (4 x 3; those of a side
    with fewer than ``min_points`` points mean nothing) and which points the last pass kept
    (N). The four sides are fitted together (their moments in one product, one batched 3 x 3
    solve per pass). With ``bow_z`` > 0, a side whose ``c2`` lies within ``bow_z`` standard
    errors of 0 (its points' scatter about the curve, times ``shared_noise`` where neighbouring
    points share their noise) is the least-squares line through the points kept instead."""
    powers = along[:, None] ** _POWERS  # (N, 5): s^0 .. s^4
    data = np.concatenate([powers, across[:, None] * powers[:, :3]], axis=1)  # (N, 8)
    one_hot = side == _SIDES  # (4, N)
    keep = use
    coef = np.zeros((4, 3))
    for reach in _REACH:
        sums = (one_hot & keep) @ data  # (4, 8): each side's moments of s, and of d s^k
        normal_eq = sums[:, _SQUARE]  # (4, 3, 3)
        normal_eq[sums[:, 0] < min_points] = np.eye(3)  # too few points: any solution, unused
        coef = np.linalg.solve(normal_eq, sums[:, 5:, None])[..., 0]  # (4, 3)
        residual = across - on_curve(coef, side, along)
        keep = use & (np.abs(residual) <= reach * max_offset_px)
    if bow_z > 0.0:
        coef = _unless_bowed(coef, along, across, side, keep, bow_z, shared_noise, min_points)
    return coef, keep


def _unless_bowed(
    coef: FloatArray,
    along: FloatArray,
    across: FloatArray,
    side: NDArray[np.intp],
    keep: NDArray[np.bool_],
    bow_z: float,
    shared_noise: float,
    min_points: int,
) -> FloatArray:
    """``coef`` (4 x 3) with each side whose ``c2`` is not ``bow_z`` standard errors clear of 0
    refitted as a line (``c2`` = 0) through its ``keep`` points (see :func:`side_curves`)."""
    one_hot = (side == _SIDES) & keep  # (4, N)
    count = one_hot.sum(axis=1)
    powers = along[:, None] ** _POWERS
    sums = one_hot @ np.concatenate([powers, across[:, None] * powers[:, :2]], axis=1)
    normal_eq = sums[:, _SQUARE]
    enough = count > 3
    normal_eq[~enough] = np.eye(3)
    residual = across - on_curve(coef, side, along)
    scatter = shared_noise * (one_hot @ residual**2) / np.maximum(count - 3, 1)
    variance = scatter * np.linalg.inv(normal_eq)[:, 2, 2]
    straight = enough & (count >= min_points) & (coef[:, 2] ** 2 <= bow_z**2 * variance)
    line_eq = normal_eq[:, :2, :2]
    line = np.linalg.solve(line_eq, sums[:, 5:7, None])[..., 0]  # (4, 2)
    flat = np.concatenate([line, np.zeros((4, 1))], axis=1)
    return np.where(straight[:, None], flat, coef)


def on_curve(coef: FloatArray, side: NDArray[np.intp], along: FloatArray) -> FloatArray:
    """The offset across its side [px] of the curve ``coef`` (4 x 3, see :func:`side_curves`) of
    each point's ``side`` (N) at its position ``along`` it (N)."""
    fitted = coef[side]  # (N, 3): each point's side's coefficients
    return fitted[:, 0] + along * (fitted[:, 1] + along * fitted[:, 2])


def _nearest_side(points: FloatArray, quad: FloatArray, edge: FloatArray) -> NDArray[np.intp]:
    """Index k of the side ``quad[k] -> quad[k] + edge[k]`` each point (N x 2) lies nearest to."""
    length2 = np.maximum(np.einsum("kc,kc->k", edge, edge), 1e-12)
    rel = points[:, None, :] - quad[None, :, :]  # (N, 4, 2)
    along = np.clip(np.einsum("nkc,kc->nk", rel, edge) / length2, 0.0, 1.0)
    gap = rel - along[..., None] * edge[None, :, :]
    return np.argmin(np.einsum("nkc,nkc->nk", gap, gap), axis=1)
