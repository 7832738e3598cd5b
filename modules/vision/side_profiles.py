"""A fitted side measured again along its whole length, by a profile every few pixels.

The edge fit (:mod:`umbra.modules.vision.edge_fit`) measures one profile under each snake
vertex, about one every 10 px, and :mod:`umbra.modules.vision.straight_sides` fits each side's
curve to those points. A side 80 px long thus rests on 6 to 12 profiles of a pixel's width,
while the patch's edge runs through 80 px of pixels: most of the evidence is never read, and
sensor noise and JPEG's blocks leave each side a few tenths of a pixel off (at 640 x 480, where
a patch 80 x 140 px loses a percent of IoU per 0.25 px a side).

Once the sides are known, each is measured again: ``profiles`` across it, evenly spaced along
the middle of its length (clear of its corners by ``MARGIN_SHARE`` of it, where the next side's
edge enters the profile) and at least ``MIN_SPACING_PX`` apart, each put on the edge by the same
crossing passes (:func:`~umbra.modules.vision.edge_fit.measure_near_edge`), and the side's curve is
fitted to them by the same rule as before
(:func:`~umbra.modules.vision.straight_sides.side_curves`), except that it bows only where the
bow stands clear of the profiles' noise (``BOW_Z``). The contour's points on the side's curve are
moved onto the new one where their own edge lies near it (``STAY_REACH``: the bent end of a side
next to a cut corner stays bent); the corners are then met as before
(:mod:`umbra.modules.vision.side_corners`). On 30 harsh frames of the tuning photographs at
640 x 480 this takes the sides' RMS offset from 0.125 to 0.085 px; on 480 harsh held-out ones
(``benchmarks/bench_snake.py --photos-only --photo-seeds 11,12,13,14,21,22,23,24,25,26,27,28``)
the frames below IoU 0.99 from 6 to 3, and the mean IoU from 0.9960 to 0.9967. It costs about
1.1 ms a tracking update where the sides are fitted (a patch up to about 300 px a side).

Pixels: u right, v down.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from umbra.modules.vision.edge_fit import EdgeFit
from umbra.modules.vision.straight_sides import SideFit, on_curve, side_curves

FloatArray = NDArray[np.float64]

#: The share of a side's length at either end where no profile is laid: within it the profile's
#: inner end nears the next side's edge (a tenth of a side 80 px long is 8 px, twice the
#: profile's default half-length).
MARGIN_SHARE = 0.1

#: A side's new curve bows only where its bow stands this many standard errors clear of none
#: (else it is the least-squares line): a bow that the profiles' noise explains would carry
#: that noise to the corners, where the sides' lines meet.
BOW_Z = 3.0
#: About this many neighbouring profiles share their noise (JPEG's errors come in blocks of 8 x
#: 8 pixels, which hold two or three profiles 2-4 px apart): the scatter about a side's curve is
#: counted this many times over.
SHARED_NOISE = 3.0
#: A point on a side's curve is moved onto the new curve when the edge it was measured at lies
#: within this many times ``max_offset_px`` of it (the reach of the side fit's second pass: the
#: new curve may lie a few tenths of a pixel off the old one, and a point left as measured
#: keeps its noise); else it is left as measured.
STAY_REACH = 2.0
#: Closest spacing of a side's profiles [px]: closer ones read the same pixels (the bilinear
#: samples span two).
MIN_SPACING_PX = 1.0

#: Measures edge points (N x 2 px) along unit outward normals (N x 2): the edge fit.
EdgeMeasure = Callable[[FloatArray, FloatArray], EdgeFit]


def remeasure_sides(
    fit: SideFit,
    measured_points: FloatArray,
    outward: FloatArray,
    measure: EdgeMeasure,
    profiles: int,
    max_offset_px: float,
    min_points: int = 6,
) -> SideFit:
    """``fit`` with each of its fitted sides' curves measured again by ``profiles`` profiles
    (see the module's text) and its points on a side's curve moved onto the new one, if the
    edge point each was measured at (``measured_points``, N x 2 px, the points ``fit`` was
    fitted to) lies within ``STAY_REACH`` times ``max_offset_px`` of the new curve; the others
    are put back where they were measured and are on no curve (the end of a side that a cut
    corner bent away stays bent, for the sanity checks to see). ``outward`` (N x 2) holds the
    unit outward normals of the points; ``max_offset_px`` and ``min_points`` are
    :func:`~umbra.modules.vision.straight_sides.side_curves`'. A side whose new profiles leave
    fewer than ``min_points`` points, or fewer than half of them, on its curve keeps its
    curve."""
    length = np.hypot(*fit.edge.T)
    usable = length * (1.0 - 2.0 * MARGIN_SHARE)
    most = np.floor(usable / MIN_SPACING_PX).astype(int) + 1
    counts = np.where(fit.fitted, np.minimum(most, profiles), 0)
    if counts.sum() == 0:
        return fit
    side = np.repeat(np.arange(4), counts)
    # Evenly spaced along each side's middle: s from MARGIN_SHARE to 1 - MARGIN_SHARE.
    start = np.concatenate([[0], np.cumsum(counts)[:-1]])
    rank = np.arange(len(side)) - start[side]
    share = np.where(counts[side] > 1, rank / np.maximum(counts[side] - 1, 1), 0.5)
    along = MARGIN_SHARE + (1.0 - 2.0 * MARGIN_SHARE) * share
    # Which way is out on each side: the sign of the contour's outward normals across it.
    one_hot = fit.side == np.arange(4)[:, None]  # (4, N)
    sign = np.where(np.einsum("kn,nc,kc->k", one_hot, outward, fit.across) < 0.0, -1.0, 1.0)
    normals = sign[side, None] * fit.across[side]
    points = (
        fit.quad[side]
        + along[:, None] * fit.edge[side]
        + on_curve(fit.curve, side, along)[:, None] * fit.across[side]
    )
    measured = measure(points, normals)
    across = np.einsum("nc,nc->n", measured.vertices - fit.quad[side], fit.across[side])
    curve, kept = side_curves(
        along, across, side, measured.found, max_offset_px, min_points, BOW_Z, SHARED_NOISE
    )
    on_new = np.bincount(side[kept], minlength=4)
    better = fit.fitted & (on_new >= min_points) & (2 * on_new >= counts)
    curve = np.where(better[:, None], curve, fit.curve)
    # Each point's measured offset across its side, against the new curve there.
    rel = measured_points - fit.quad[fit.side]
    offset = np.einsum("nc,nc->n", rel, fit.across[fit.side]) - on_curve(curve, fit.side, fit.along)
    renewed = fit.on_curve & better[fit.side]
    stays = renewed & (np.abs(offset) <= STAY_REACH * max_offset_px)
    moved = fit.points.copy()
    moved[stays] = measured_points[stays] - offset[stays, None] * fit.across[fit.side[stays]]
    off = renewed & ~stays
    moved[off] = measured_points[off]
    return replace(fit, points=moved, curve=curve, on_curve=fit.on_curve & ~off)
