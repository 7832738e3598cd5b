"""How well a sketched vertex's depth is constrained, and what the operator is told.

A right-hand (image b) vertex rides on the epipolar line of its image-a mate; where along that
line it sits sets its depth. The operator leaves it where they believe the point is. On a vertex
with edges (a line's ends, a plane's or a triad's corners) that belief is spread by the edge
itself: across an edge a person places a handle to the click noise ``sigma_c``
(``StereoNoise.pixel_px``), along a featureless edge only to the handle error ``sigma_h``
(``StereoNoise.handle_px``: where on a plain pipe "the same point" is, judged by eye). The
belief's information is ``W = sum_k (n_k n_k^T / sigma_c² + t_k t_k^T / sigma_h²)`` over the
vertex's edges ``k`` (unit direction ``t_k`` and normal ``n_k`` in image b), capped at
``1 / sigma_c²`` in every direction; its spread ``W^-1`` (:func:`handle_spread`) goes to
:meth:`StereoPair.triangulate_constrained`, which takes the handle to the spot of the epipolar
line ``e`` most consistent with it. The error along the line is then
``1 / sqrt(e^T W e) = 1 / sqrt(sum_k sin²(theta_k) / sigma_c² + cos²(theta_k) / sigma_h²)``
with ``theta_k`` the angle between edge ``k`` and ``e``: an edge across the epipolar lines pins
the vertex (``sigma_c``), an edge along them leaves ``sigma_h``. A vertex without edges (a
point) is taken to sit on a distinct feature: ``sigma_c`` in every direction.

A vertex is flagged when every edge it has runs within :data:`WARN_ANGLE_DEG` of its epipolar
line (there its depth error is about three click noises or more, up to the handle error): the
warning says so in words, with the depth moved per pixel along the line, the stated sigma and
what to do. Angles in degrees, pixels as image b shows them, millimetres in the words.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from umbra.connectors.sketch_messages import SketchPrimitive
from umbra.modules.sketch.stereo import StereoNoise, StereoPair

FloatArray = NDArray[np.float64]

#: a vertex whose image-b edges all run within this angle of its epipolar line is flagged (deg)
WARN_ANGLE_DEG = 20.0

#: what the operator can do about a flagged primitive (said in every warning). Another pan of
#: the same two cameras is not offered: each camera turns about (nearly) its own centre, the
#: baseline stays, and so do the epipolar lines (``bench_sketch.py``'s "re-placed from another
#: pan" row: no flagged primitive of a macro stopped being flagged)
REMEDY = (
    "place its vertices on features that cross the epipolar lines (an end, a joint, a mark), "
    "or check it in the live wrist view before the arm moves; another pan of the same cameras "
    "does not help (the epipolar lines stay where they are)"
)


@dataclass(frozen=True)
class VertexDepth:
    """One vertex's depth condition.

    Attributes:
        angle_deg: the largest angle in image b between one of its edges and its epipolar line
            (deg; None: no edge, a point on a feature).
        flagged: its depth rests on where its handle sits along an edge (angle below
            :data:`WARN_ANGLE_DEG`).
    """

    angle_deg: float | None
    flagged: bool


def edge_angles_deg(
    pair: StereoPair, pixels_a: ArrayLike, pixels_b: ArrayLike, edges: ArrayLike
) -> list[FloatArray]:
    """Per vertex, the angles (deg, 0 .. 90) in image b between each of its edges and its
    epipolar line (empty for a vertex without edges)."""
    uv_a = np.asarray(pixels_a, dtype=float).reshape(-1, 2)
    uv_b = np.asarray(pixels_b, dtype=float).reshape(-1, 2)
    e = pair.epipolar_direction_b(uv_a, uv_b).reshape(-1, 2)
    angles: list[list[float]] = [[] for _ in uv_a]
    for i, j in np.asarray(edges, dtype=int).reshape(-1, 2):
        t = uv_b[j] - uv_b[i]
        length = float(np.linalg.norm(t))
        for k in (i, j):
            if length < 1e-9:  # a collapsed edge: no direction, no crossing
                angles[k].append(0.0)
                continue
            cos = min(1.0, abs(float(t @ e[k])) / length)
            angles[k].append(float(np.degrees(np.arccos(cos))))
    return [np.asarray(a) for a in angles]


def handle_spread(pixels_b: ArrayLike, edges: ArrayLike, noise: StereoNoise) -> FloatArray | None:
    """Per vertex, the covariance (px², (n, 2, 2), image b) of where the operator believes it is
    (module docstring); None when the handle error is no larger than the click noise (then the
    click noise alone, in every direction)."""
    uv_b = np.asarray(pixels_b, dtype=float).reshape(-1, 2)
    if noise.handle_px <= noise.pixel_px:
        return None
    sigma_c = max(noise.pixel_px, 1e-3)  # a zero click noise: pinned across, not singular
    cap = 1.0 / sigma_c**2
    info = np.zeros((len(uv_b), 2, 2))
    has_edge = np.zeros(len(uv_b), dtype=bool)
    for i, j in np.asarray(edges, dtype=int).reshape(-1, 2):
        t = uv_b[j] - uv_b[i]
        length = float(np.linalg.norm(t))
        if length < 1e-9:
            continue
        t = t / length
        n = np.array([-t[1], t[0]])
        block = cap * np.outer(n, n) + np.outer(t, t) / noise.handle_px**2
        for k in (i, j):
            info[k] += block
            has_edge[k] = True
    spread = np.empty_like(info)
    for k in range(len(uv_b)):
        if not has_edge[k]:
            spread[k] = sigma_c**2 * np.eye(2)
            continue
        values, vectors = np.linalg.eigh(info[k])
        spread[k] = (vectors / np.minimum(values, cap)) @ vectors.T
    return spread


def vertex_depths(pair: StereoPair, primitive: SketchPrimitive) -> list[VertexDepth]:
    """Each vertex's depth condition (see the module docstring)."""
    angles = edge_angles_deg(pair, primitive.pixels_a, primitive.pixels_b, primitive.edges)
    out = []
    for a in angles:
        widest = float(np.max(a)) if len(a) else None
        out.append(VertexDepth(widest, widest is not None and widest < WARN_ANGLE_DEG))
    return out


def mm_per_px_along(pair: StereoPair, pixel_a: ArrayLike, pixel_b: ArrayLike) -> float:
    """How far (mm) a vertex moves per pixel its image-b handle moves along its epipolar line."""
    a = np.asarray(pixel_a, dtype=float).reshape(2)
    b = np.asarray(pixel_b, dtype=float).reshape(2)
    e = pair.epipolar_direction_b(a, b)
    plus = pair.triangulate(a, pair.constrain_b(a, b + e))[0]
    minus = pair.triangulate(a, pair.constrain_b(a, b - e))[0]
    return float(np.linalg.norm(plus - minus)) * 1e3 / 2.0


def depth_warnings(pair: StereoPair, primitive: SketchPrimitive) -> list[str]:
    """The primitive's warnings in words (empty when every vertex's depth is well constrained):
    which vertices, their angle to the epipolar lines, mm per pixel along them, the stated
    sigma, and what to do (:data:`REMEDY`)."""
    depths = vertex_depths(pair, primitive)
    flagged = [i for i, d in enumerate(depths) if d.flagged]
    if not flagged:
        return []
    sigma_mm = np.sqrt(np.linalg.eigvalsh(np.asarray(primitive.covariances))[:, -1]) * 1e3
    per_px = [mm_per_px_along(pair, primitive.pixels_a[i], primitive.pixels_b[i]) for i in flagged]
    widest = max(depths[i].angle_deg or 0.0 for i in flagged)
    which = primitive.primitive_id
    if len(flagged) < len(depths) or primitive.kind in ("plane", "triad"):
        word = "vertex" if len(flagged) == 1 else "vertices"
        which += f" {word} {', '.join(str(i) for i in flagged)}"
    return [
        f"{which}: depth poorly constrained: in image b it runs within {widest:.1f} deg of the "
        f"epipolar lines, so where its handles sit along it sets its depth "
        f"({max(per_px):.1f} mm per px along the line; stated sigma "
        f"{max(sigma_mm[flagged]):.0f} mm). To trust it, {REMEDY}."
    ]
