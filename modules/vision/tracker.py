"""Frame-to-frame tracking with the snake: seed, acquire, follow, check, adapt.

:class:`SnakeTracker` strings the pure pieces together the way the vsSnake module uses them:
the first frame after a seed grows (or collapses) the snake until it converges; each later
frame runs a few iterations from the previous contour; every frame ends with the sanity checks
against the previous frame's features. A failure latches (the status stays "failed" with its
first reason until the next seed), because the servo must not resume on its own after the
snake has been seen to go wrong. While tracking is sane, the color model adapts from pixels
just inside the contour.

Besides the shape checks of :mod:`umbra.modules.vision.sanity`, the snake itself fails when it
cannot be on a target: its colour model is gray (a grayscale or colourless image: ``min_chroma``),
no colour edge lies under most of its vertices (a featureless image: ``min_edge_fraction``), it
reaches the image border (the target is cut by the frame, its features are not the target's),
it collapsed, or it did not converge (at acquisition, or ``max_unconverged_frames`` frames in a
row while tracking).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from umbra.connectors.tracking import SnakeCheck, TrackStatus
from umbra.modules.vision import color
from umbra.modules.vision.color import ColorModel
from umbra.modules.vision.features import PolygonFeatures
from umbra.modules.vision.sanity import FAILED, SanityLimits, SanityResult, check_contour
from umbra.modules.vision.snake import (
    SnakeParams,
    SnakeResult,
    evolve,
    interior_samples,
    seed_point,
    seed_region,
    seed_samples,
)
from umbra.modules.vision.transfer import to_codes, to_light

FloatArray = NDArray[np.float64]

IDLE = TrackStatus.IDLE


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
        self._unconverged = 0
        #: The last frame-to-frame motion of the contour: centroid step [px], turn [rad], scale.
        self._motion: tuple[FloatArray, float, float] | None = None

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
        self._unconverged = 0
        self._motion = None

    def update(self, image: NDArray[np.uint8]) -> TrackUpdate:
        """Evolve the snake on a new frame and check it. Raises RuntimeError before a seed."""
        if self.vertices is None or self.model is None:
            raise RuntimeError("the tracker has not been seeded")
        acquiring = self._acquiring
        budget = self.params.max_iterations if acquiring else self.params.track_iterations
        gray = color_is_gray(self.model, self.params.min_chroma)
        start = time.perf_counter()
        lit = self.params
        if gray:  # nothing to tell the target from: do not grow over the whole image
            result = SnakeResult(self.vertices, 0, False, 0.0, edge_fraction=0.0)
        else:
            start_vertices = self._predicted(self.vertices)
            lit = self._lit(image, start_vertices)
            result = evolve(image, start_vertices, self.model, lit, max_iterations=budget)
            if acquiring and result.converged:
                result = self._grown_with_its_interior(image, result, budget, lit)
        elapsed = time.perf_counter() - start
        self._acquiring = False
        self.vertices = result.vertices
        self._unconverged = 0 if settled(result, self.params) else self._unconverged + 1
        outline = result.outline
        sanity = check_contour(outline, self.limits, self._previous, self._reference)
        failures = self._snake_failures(result, gray, acquiring)
        if failures:
            reasons = tuple(text for _check, text in failures) + sanity.reasons
            checks = tuple(check for check, _text in failures) + sanity.checks
            sanity = replace(
                sanity, status=FAILED, reason="; ".join(reasons), reasons=reasons, checks=checks
            )
        self._motion = _motion(self._previous, sanity.features) if sanity.ok else None
        if sanity.features is not None:
            self._previous = sanity.features
            if self._reference is None and sanity.ok:
                self._reference = sanity.features
        if self._latched is None and not sanity.ok:
            self._latched = sanity
        if self._latched is not None:
            latched = self._latched
            sanity = replace(
                sanity,
                status=FAILED,
                reason=latched.reason,
                reasons=latched.reasons,
                checks=latched.checks,
            )
        elif lit.adapt_rate > 0.0:
            samples = interior_samples(image, result.vertices, lit)
            self.model = color.adapt(self.model, samples, lit.adapt_rate, min_gray=lit.min_gray)
        return TrackUpdate(outline, sanity, result.iterations, result.converged, elapsed)

    def _grown_with_its_interior(
        self, image: NDArray[np.uint8], first: SnakeResult, budget: int, lit: SnakeParams
    ) -> SnakeResult:
        """Acquisition's second pass: the colour learned again from the interior the first pass
        found, and the snake evolved again from there with it, within what is left of the budget
        (the second pass takes a few iterations when the first already lay on the edge). A second
        pass that does not converge leaves the first pass and the seed's model as they were.

        A seed sees a few pixels at the patch's centre; towards the edges the patch's colour
        varies more than there (JPEG's chroma spread over its 16-pixel blocks, shading), and a
        model that never saw it stops the snake pixels short of the edge, further than the edge
        fit reaches. The samples inside the first contour, gated by the seed's model as adaptation
        gates them (:func:`umbra.modules.vision.color.adapt` at rate 1), replace the seed's
        statistics."""
        assert self.model is not None
        samples = interior_samples(image, first.vertices, lit)
        model = color.adapt(self.model, samples, 1.0, min_gray=lit.min_gray)
        left = budget - first.iterations
        if model is self.model or left < 1:  # nothing learned, or no budget left
            return first
        second = evolve(image, first.vertices, model, lit, max_iterations=left)
        if not second.converged:
            return first
        self.model = model
        return replace(second, iterations=first.iterations + second.iterations)

    def _lit(self, image: NDArray[np.uint8], vertices: FloatArray) -> SnakeParams:
        """The snake's parameters on this frame: ``min_gray`` raised to the gray level of
        ``dim_share`` of the patch's light in it (of the median gray level of the
        target-coloured pixels halfway from the centroid of ``vertices`` (px) to each vertex),
        when that is higher. A patch's chromaticity does not change with the light, so a
        blurred patch's halo on a dark background, or a dark surface of the patch's hue, passes
        the colour gate: the snake grew into it. Measured on the frame itself, the floor
        follows any change of the light at once. Unchanged when fewer than 8 pixels inside are
        the target's colour."""
        p = self.params
        if p.dim_share <= 0.0 or self.model is None:
            return p
        height, width = image.shape[:2]
        inside = (0.5 * (vertices + vertices.mean(axis=0)) + 0.5).astype(np.intp)
        np.clip(inside, 0, [width - 1, height - 1], out=inside)
        samples = image[inside[:, 1], inside[:, 0]].astype(np.float32)
        patch = samples[color.is_target(self.model, samples, p.k_sigma, p.min_gray)]
        if len(patch) < _LEAST_LIT_SAMPLES:
            return p
        # a share of the patch's light, in the codes the gate reads (an sRGB code of 0.4 of
        # the patch's code is 0.13 of its light)
        gray = float(np.median(patch.sum(axis=1))) / 3.0
        floor = p.dim_share * gray
        if p.image_encoding != "linear":
            light = to_light(np.array([gray]), p.image_encoding)
            floor = float(to_codes(p.dim_share * light, p.image_encoding)[0])
        return replace(p, min_gray=floor) if floor > p.min_gray else p

    def _predicted(self, vertices: FloatArray) -> FloatArray:
        """Where the contour should be on the new frame if the target keeps the motion of the
        last frame (a constant-velocity guess: the snake then starts near the edge and settles
        in a few iterations); the vertices unchanged without a motion."""
        if self._motion is None or self._previous is None:
            return vertices
        step, turn, scale = self._motion
        centre = np.asarray(self._previous.centroid_uv)
        c, s = np.cos(turn), np.sin(turn)
        rotation = scale * np.array([[c, s], [-s, c]])  # row vectors: x @ R^T
        return centre + step + (vertices - centre) @ rotation

    def _snake_failures(
        self, result: SnakeResult, gray: bool, acquiring: bool
    ) -> list[tuple[SnakeCheck, str]]:
        """Why the snake itself cannot be on a target, each as a code and in exact words (empty
        when it can)."""
        p = self.params
        if gray:
            return [
                (
                    SnakeCheck.GRAY_TARGET,
                    f"target colour is gray (chromaticity within {p.min_chroma:g} of gray): a "
                    "grayscale or colourless image cannot be tracked by colour",
                )
            ]
        if result.collapsed:
            return [(SnakeCheck.SNAKE_COLLAPSED, "snake collapsed: no target color left under it")]
        failures = []
        if result.edge_fraction < p.min_edge_fraction:
            failures.append(
                (
                    SnakeCheck.NO_EDGE,
                    f"no colour edge under {100 * (1 - result.edge_fraction):.0f}% of the contour "
                    "(featureless image)",
                )
            )
        if result.touches_border:
            failures.append((SnakeCheck.TOUCHES_BORDER, "contour touches the image border"))
        if acquiring and not result.converged:
            text = f"snake did not converge in {result.iterations} iterations"
            failures.append((SnakeCheck.NOT_CONVERGED, text))
        elif self._unconverged >= p.max_unconverged_frames:
            failures.append(
                (
                    SnakeCheck.NOT_CONVERGED,
                    f"snake did not converge for {self._unconverged} frames in a row",
                )
            )
        return failures


def settled(result: SnakeResult, params: SnakeParams) -> bool:
    """Whether a tracking snake came to rest: converged, or still creeping by less than half a
    pressure step per iteration when its budget ran out (a contour following a moving target
    keeps sliding a little; one that is still being pushed at half strength or more is not on
    an edge). Acquisition, with its large budget, must converge."""
    return result.converged or result.last_motion_px < 0.5 * params.step_px * result.scale


def _motion(
    before: PolygonFeatures | None, after: PolygonFeatures | None
) -> tuple[FloatArray, float, float] | None:
    """Centroid step [px], turn [rad] and scale of a contour from one frame to the next (turn
    and scale bounded: a guess, not a measurement)."""
    if before is None or after is None or before.area_px2 <= 0:
        return None
    step = np.subtract(after.centroid_uv, before.centroid_uv)
    turn = (after.orientation_rad - before.orientation_rad + np.pi / 2) % np.pi - np.pi / 2
    turn = float(np.clip(turn, -_MAX_PREDICTED_TURN_RAD, _MAX_PREDICTED_TURN_RAD))
    scale = float(np.clip(np.sqrt(after.area_px2 / before.area_px2), 0.9, 1.1))
    return step, turn, scale


#: Fewest target-coloured pixels inside the contour that tell the patch's brightness on a frame.
_LEAST_LIT_SAMPLES = 8
#: Largest turn per frame the motion guess carries over [rad].
_MAX_PREDICTED_TURN_RAD = np.deg2rad(10.0)


def color_is_gray(model: ColorModel, min_chroma: float) -> bool:
    """True when the model's mean chromaticity lies within ``min_chroma`` of gray (1/3, 1/3)."""
    return bool(np.hypot(*(model.mean - 1.0 / 3.0)) < min_chroma)
