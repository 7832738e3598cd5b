"""The camera's transfer curve: how the codes of an 8-bit image stand for light.

Across a blurred edge a pixel mixes the two sides' *light* in proportion to their areas; the
sub-pixel edge (:mod:`umbra.modules.vision.edge_fit`) finds the edge where that mixing is one
half. A machine-vision or raw camera writes codes proportional to light (``linear``). Webcams,
phones and most cameras that write JPEG encode the light by the sRGB curve first (``srgb``,
IEC 61966-2-1: about code ∝ light^(1/2.2)); read as codes, an edge's half-way point then lies
towards its dark side (a Gaussian blur of 1 px between a 10 % and an 80 % light level: 0.3 px).
The edge is therefore measured on the light the codes stand for, on the same 0..255 scale
(code 0 and code 255 are light 0 and 255).

The curves are continued beyond 255 by the same power law: a clipped channel put back above the
sensor's top (:func:`umbra.modules.vision.color.unclip`) keeps a meaning in light.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Literal

import numpy as np
from numpy.typing import NDArray

#: The image encodings the snake knows: codes proportional to light, or sRGB-encoded light.
Encoding = Literal["linear", "srgb"]

_TOP = 255.0
# The sRGB curve's constants (IEC 61966-2-1): a linear toe, then a 2.4 power with an offset.
_TOE_CODE, _TOE_LIGHT, _TOE_SLOPE = 0.04045, 0.0031308, 12.92
_OFFSET, _POWER = 0.055, 2.4


def to_light(codes: NDArray[np.floating], encoding: Encoding) -> NDArray[np.float32]:
    """The light (any shape, 0..255 scale, float32) that image ``codes`` (0..255, or above for a
    channel put back above the sensor's top) stand for under ``encoding``."""
    x = np.asarray(codes, dtype=np.float32)
    if encoding == "linear":
        return x
    c = np.maximum(x, 0.0) / _TOP
    curve = np.power((c + _OFFSET) / (1.0 + _OFFSET), _POWER)
    return (np.where(c <= _TOE_CODE, c / _TOE_SLOPE, curve) * _TOP).astype(np.float32)


def to_codes(light: NDArray[np.floating], encoding: Encoding) -> NDArray[np.float32]:
    """The codes (0..255 scale, float32, unrounded and unclipped above) that encode ``light``
    (0..255 scale) under ``encoding``: the inverse of :func:`to_light`."""
    x = np.asarray(light, dtype=np.float32)
    if encoding == "linear":
        return x
    lin = np.maximum(x, 0.0) / _TOP
    curve = (1.0 + _OFFSET) * np.power(lin, 1.0 / _POWER) - _OFFSET
    return (np.where(lin <= _TOE_LIGHT, lin * _TOE_SLOPE, curve) * _TOP).astype(np.float32)


@lru_cache(maxsize=4)
def light_table(encoding: Encoding) -> NDArray[np.float32]:
    """The light of each of the 256 codes (indexed by the code), read-only."""
    table = to_light(np.arange(256, dtype=np.float32), encoding)
    table.setflags(write=False)
    return table
