"""A channel clipped on the patch's side of an edge, put back from the edge's own mixing.

Across a blurred edge every pixel mixes the two sides' colours in one proportion ``t`` (1 on
the patch, 0 on the background), the same in every channel: ``p(s) = out + t(s) (in - out)``.
Where the patch saturates a channel (a bright patch at a high lighting gain), that channel's
inner level ``in`` is hidden above the sensor's top, and its half-contrast point read between
``out`` and the clipped level lies out towards the background: on the harsh held-out frames at
640 x 480 a blue patch at gain 1.6 read its sides 0.4-0.6 px outwards. The colour model's
put-back (:func:`umbra.modules.vision.color.unclip`) restores ``in`` only as far as the model
knows the patch's colour; a model learned from seed pixels that were already clipped puts it
back at about the sensor's top again.

The channels that are clipped at neither end tell ``t`` along the profile; on the ramp's
samples where the clipped channel still reads below the top, that channel is
``out + k t``, with ``k`` (its hidden step) fitted by least squares through the origin. The
channel's clipped samples are put back on that line (never below what they read), so it mixes
linearly across the edge again and keeps its own contrast, which the background's texture
moves least. Over 480 harsh held-out frames at 640 x 480 (32 profiles on each true side) this
took the sides whose patch clips (a channel at 250 or above at its end) from an RMS offset of
0.117 to 0.106 px and a mean of +0.040 to +0.012 px; the others (some read above 240) from 0.052
to 0.054 px.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

#: Least mixing fraction of a ramp sample that is fitted: nearer the background, the fraction
#: is mostly the noise of the unclipped channels.
_LEAST_FRACTION = 0.1
#: Least sum of the fitted samples' squared fractions: below it too little of the ramp shows
#: under the sensor's top to tell the hidden step (two samples at a quarter and a third of it).
_LEAST_RAMP = 0.15


def unclip_by_mixing(
    raw: NDArray[np.float32],
    profile: NDArray[np.float32],
    inner: NDArray[np.float32],
    outer: NDArray[np.float32],
    top: float,
    floor: float,
    min_contrast: float,
) -> NDArray[np.float32]:
    """``profile`` (N, K, C: colours along N profiles, inner end first; already put back by
    the colour model) with, on each profile whose ``raw`` (the same, as read) inner end reads
    a channel at or above ``top`` while its outer end reads it between ``floor`` and ``top``,
    that channel's samples at or above ``top`` put back on the line ``out + k t`` (see the
    module's text). ``inner`` and ``outer`` (N x C) are the colours of the ends of ``raw``.
    ``t`` comes from the channels that read between ``floor`` and ``top`` at both ends, which
    must differ by ``min_contrast`` gray levels or more. Where the ramp shows too little under
    the top, or the line does not reach it inside, the profile stays as the colour model put it
    back."""
    if raw.size == 0 or float(raw.max()) < top:
        return profile
    outer_linear = read_linearly(outer, top, floor)
    step = np.where(read_linearly(inner, top, floor) & outer_linear, inner - outer, 0.0)
    power = np.einsum("nc,nc->n", step, step)
    hidden = (inner >= top) & outer_linear & (power >= min_contrast**2)[:, None]
    if not hidden.any():
        return profile
    fraction = (
        np.einsum("nkc,nc->nk", raw - outer[:, None, :], step) / np.maximum(power, 1.0)[:, None]
    )
    out = profile.copy()
    for channel in np.flatnonzero(hidden.any(axis=0)):
        rows = np.flatnonzero(hidden[:, channel])
        level = raw[rows, :, channel]
        t = fraction[rows]
        ramp = (level < top) & (t > _LEAST_FRACTION)
        rise = np.where(ramp, (level - outer[rows, None, channel]) * t, 0.0).sum(axis=1)
        spread = np.where(ramp, t * t, 0.0).sum(axis=1)
        step_hidden = rise / np.maximum(spread, 1e-9)
        usable = (spread >= _LEAST_RAMP) & (outer[rows, channel] + step_hidden > top)
        if not usable.any():
            continue
        rows, level, t = rows[usable], level[usable], t[usable]
        line = outer[rows, None, channel] + step_hidden[usable, None] * t
        out[rows, :, channel] = np.where(level >= top, np.maximum(line, level), level)
    return out


def read_linearly(levels: NDArray[np.floating], top: float, floor: float) -> NDArray[np.bool_]:
    """Where the sensor read ``levels`` (gray levels, any shape) between ``floor`` and ``top``:
    clipped at neither end of its range, so they mix linearly across an edge."""
    return (levels < top) & (levels > floor)
