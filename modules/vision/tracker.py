"""Frame-to-frame tracking with the snake: seed, acquire, follow, check, adapt.

:class:`SnakeTracker` strings the pure pieces together the way the vsSnake module uses them:
the first frame after a seed grows (or collapses) the snake until it converges; each later
frame runs a few iterations from the previous contour; every frame ends with the sanity checks
against the previous frame's features. A failure latches (the status stays "failed" with its
first reason until the next seed), because the servo must not resume on its own after the
snake has been seen to go wrong. While tracking is sane, the color model adapts from pixels
just inside the contour.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from modules.vision import color
from modules.vision.color import ColorModel
from modules.vision.features import PolygonFeatures
from modules.vision.sanity import FAILED, SanityLimits, SanityResult, check_contour
from modules.vision.snake import (
    SnakeParams,
    evolve,
    interior_samples,
    seed_point,
    seed_region,
    seed_samples,
)

FloatArray = NDArray[np.float64]

IDLE = "idle"


@dataclass(frozen=True, eq=False)
class TrackUpdate:
    """The outcome of one frame: contour ``vertices`` (N x 2 px), ``sanity`` (status, reason,
    features, offending vertices, bounding shapes), snake ``iterations``, whether it
    ``converged``, and ``snake_time_s`` the wall time of the snake iterations alone [s]."""

    vertices: FloatArray
    sanity: SanityResult
    iterations: int
    converged: bool
    snake_time_s: float

    @property
    def status(self) -> str:
        return self.sanity.status

    @property
    def features(self) -> PolygonFeatures | None:
        return self.sanity.features


class SnakeTracker:
    """A snake that follows one target through successive frames (H x W x 3 uint8 BGR)."""

    def __init__(
        self, params: SnakeParams | None = None, limits: SanityLimits | None = None
    ) -> None:
        self.params = params or SnakeParams()
        self.limits = limits or SanityLimits()
        self.model: ColorModel | None = None
        self.vertices: FloatArray | None = None
        self._previous: PolygonFeatures | None = None
        self._reference: PolygonFeatures | None = None
        self._acquiring = False
        self._latched: SanityResult | None = None

    @property
    def seeded(self) -> bool:
        return self.vertices is not None

    def seed_at_point(
        self, image: NDArray[np.uint8], seed_uv: ArrayLike, model: ColorModel | None = None
    ) -> None:
        """Seed at a point: learn the color from the pixels around it unless ``model`` is given."""
        if model is None:
            samples = seed_samples(image, seed_uv, self.params.seed_radius_px)
            model = color.fit(samples, min_gray=self.params.min_gray)
        self._reset(model, seed_point(seed_uv, self.params))

    def seed_with_region(self, region: ArrayLike, model: ColorModel) -> None:
        """Seed with a region (polygon, px) that the snake collapses from onto the target color."""
        self._reset(model, seed_region(region, self.params))

    def _reset(self, model: ColorModel, vertices: FloatArray) -> None:
        self.model = model
        self.vertices = vertices
        self._previous = None
        self._reference = None
        self._acquiring = True
        self._latched = None

    def update(self, image: NDArray[np.uint8]) -> TrackUpdate:
        """Evolve the snake on a new frame and check it. Raises RuntimeError before a seed."""
        if self.vertices is None or self.model is None:
            raise RuntimeError("the tracker has not been seeded")
        budget = self.params.max_iterations if self._acquiring else self.params.track_iterations
        start = time.perf_counter()
        result = evolve(image, self.vertices, self.model, self.params, max_iterations=budget)
        elapsed = time.perf_counter() - start
        self._acquiring = False
        self.vertices = result.vertices
        sanity = check_contour(result.vertices, self.limits, self._previous, self._reference)
        if result.collapsed and sanity.ok:
            reason = "snake collapsed: no target color left under it"
            sanity = replace(sanity, status=FAILED, reason=reason, reasons=(reason,))
        if sanity.features is not None:
            self._previous = sanity.features
            if self._reference is None and sanity.ok:
                self._reference = sanity.features
        if self._latched is None and not sanity.ok:
            self._latched = sanity
        if self._latched is not None:
            latched = self._latched
            sanity = replace(sanity, status=FAILED, reason=latched.reason, reasons=latched.reasons)
        elif self.params.adapt_rate > 0.0:
            samples = interior_samples(image, result.vertices, self.params)
            self.model = color.adapt(
                self.model, samples, self.params.adapt_rate, min_gray=self.params.min_gray
            )
        return TrackUpdate(result.vertices, sanity, result.iterations, result.converged, elapsed)
