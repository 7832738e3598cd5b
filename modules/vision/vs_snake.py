"""vsSnake: the statistical pressure snake as a module: image in, tracked contour out."""

from __future__ import annotations

from typing import Literal

import numpy as np

from umbra.connectors import Input, Module, Output, Parameters, UserError, param
from umbra.connectors.messages import Contour, Image, Vector
from umbra.modules.vision import color
from umbra.modules.vision.contour_message import contour_message
from umbra.modules.vision.polygon import rectangle
from umbra.modules.vision.sanity import FAILED, SanityLimits
from umbra.modules.vision.snake import SnakeParams, seed_samples
from umbra.modules.vision.snake_config import SettingsError, setting_defaults, settings_from
from umbra.modules.vision.tracker import IDLE, SnakeTracker

_DEFAULTS = setting_defaults()


class VsSnake(Module):
    """Tracks a colored patch with a statistical pressure snake and checks it every frame.

    Seeding: at a point (``seed_mode: point``, ``seed_uv``; the target color is learned from the
    pixels around it, as when the operator clicks the patch) or from a region that collapses
    onto the target color (``seed_mode: region``, ``seed_region``, ``target_rgb``). The
    ``seed`` input re-seeds at any time: [u, v] for a point, [u_min, v_min, u_max, v_max] for a
    region. Each new image runs the snake (to convergence on the first image after a seed, a
    few iterations per image afterwards) and sends the contour with its centroid, area,
    orientation, axes and the status of the sanity checks (outer rectangle, inner ellipse,
    size, aspect ratio, rates of change). A failure latches until the next seed, so the servo
    cannot resume on its own. A stale image (the camera stopped) gives a failed contour without
    touching the snake. Pixels: u right, v down.
    """

    TYPE = "vsSnake"

    class Params(Parameters):
        seed_mode: Literal["point", "region", "none"] = param(
            "point", "seed at start: point, region, or wait for the seed input"
        )
        seed_uv: list[float] = param(
            [320.0, 240.0], "seed point [u, v]", unit="px", min_length=2, max_length=2
        )
        seed_region: list[float] = param(
            [0.0, 0.0, 640.0, 480.0],
            "seed region [u_min, v_min, u_max, v_max]",
            unit="px",
            min_length=4,
            max_length=4,
        )
        target_rgb: list[int] = param(
            [], "target color RGB 0..255 for region seeds (empty: learn it at the region centre)"
        )
        target_noise_gray: float = param(
            8.0, "spread of the target_rgb color model", unit="gray levels", gt=0
        )
        k_sigma: float = param(
            _DEFAULTS["k_sigma"], "color gate radius", unit="sigma", gt=0, tunable=True
        )
        min_gray: float = param(
            _DEFAULTS["min_gray"], "darker pixels never count", unit="gray levels", ge=0
        )
        step_px: float = param(
            _DEFAULTS["step_px"],
            "largest pressure move per iteration",
            unit="px",
            gt=0,
            tunable=True,
        )
        tension: float = param(
            _DEFAULTS["tension"], "smoothing per iteration", ge=0, le=0.5, tunable=True
        )
        window_radius_px: int = param(
            _DEFAULTS["window_radius_px"], "half-width of the pixel window", unit="px", ge=0
        )
        min_segment_px: float = param(
            _DEFAULTS["min_segment_px"], "shorter segments trigger resampling", unit="px", gt=0
        )
        max_segment_px: float = param(
            _DEFAULTS["max_segment_px"], "longer segments trigger resampling", unit="px", gt=0
        )
        seed_radius_px: float = param(
            _DEFAULTS["seed_radius_px"], "radius of the point seed circle", unit="px", gt=0
        )
        max_iterations: int = param(
            _DEFAULTS["max_iterations"], "iterations to acquire after a seed", ge=1, le=10_000
        )
        track_iterations: int = param(
            _DEFAULTS["track_iterations"],
            "iterations per image when tracking",
            ge=1,
            le=1_000,
            tunable=True,
        )
        converge_px: float = param(
            _DEFAULTS["converge_px"], "converged when no vertex moves more", unit="px", gt=0
        )
        adapt_rate: float = param(
            _DEFAULTS["adapt_rate"], "color model adaptation per image", ge=0, le=1, tunable=True
        )
        edge_half_length_px: float = param(
            _DEFAULTS["edge_half_length_px"],
            "half-length of the sub-pixel edge profile (0: off)",
            unit="px",
            ge=0,
            le=32,
        )
        corner_turn_deg: float = param(
            _DEFAULTS["corner_turn_deg"], "sharper turns are corners put back", unit="deg", gt=0
        )
        min_edge_fraction: float = param(
            _DEFAULTS["min_edge_fraction"], "fewer vertices on an edge: failed", ge=0, le=1
        )
        border_margin_px: float = param(
            _DEFAULTS["border_margin_px"], "closer to the image border: failed", unit="px", ge=0
        )
        min_chroma: float = param(
            _DEFAULTS["min_chroma"], "a target colour closer to gray: failed", ge=0, lt=1
        )
        max_unconverged_frames: int = param(
            _DEFAULTS["max_unconverged_frames"], "frames in a row without settling: failed", ge=1
        )
        rectangle_margin: float = param(
            _DEFAULTS["rectangle_margin"], "outer rectangle growth (0.12 = 12 %)", ge=0
        )
        ellipse_scale: float = param(_DEFAULTS["ellipse_scale"], "inner ellipse scale", gt=0, le=1)
        min_area_px2: float = param(_DEFAULTS["min_area_px2"], "smallest area", unit="px²", ge=0)
        max_area_px2: float = param(_DEFAULTS["max_area_px2"], "largest area", unit="px²", gt=0)
        min_aspect: float = param(_DEFAULTS["min_aspect"], "smallest major/minor axis", ge=1)
        max_aspect: float = param(_DEFAULTS["max_aspect"], "largest major/minor axis", ge=1)
        max_centroid_jump_px: float = param(
            _DEFAULTS["max_centroid_jump_px"], "largest centroid move per image", unit="px", gt=0
        )
        max_area_change: float = param(
            _DEFAULTS["max_area_change"], "largest relative area change per image", gt=0
        )
        max_rotation_deg: float = param(
            _DEFAULTS["max_rotation_deg"], "largest rotation per image", unit="deg", gt=0
        )
        max_aspect_change: float = param(
            _DEFAULTS["max_aspect_change"], "largest relative aspect change per image", gt=0
        )
        max_aspect_drift: float = param(
            _DEFAULTS["max_aspect_drift"], "largest aspect change since the seed", gt=0
        )

        max_identical_frames: int = param(
            5, "this many identical images in a row mean a frozen camera (0: never)", ge=0
        )

    image = Input(Image, trigger=True, doc="camera frames (BGR)")
    seed = Input(Vector, required=False, doc="operator re-seed: [u, v] or [u0, v0, u1, v1] px")
    contour = Output(
        Contour, origin_from=("image",), doc="tracked contour, features and sanity status"
    )

    def _settings(self) -> tuple[SnakeParams, SanityLimits]:
        """Snake parameters and sanity limits from this module's parameters."""
        p = self.params
        names = set(_DEFAULTS) & set(type(p).model_fields)
        try:
            return settings_from({name: getattr(p, name) for name in names})
        except SettingsError as exc:
            raise UserError(f"{self.name}: {exc}") from None

    def start(self) -> None:
        p = self.params
        self._tracker = SnakeTracker(*self._settings())
        self._target = None
        if p.target_rgb:
            if len(p.target_rgb) != 3 or not all(0 <= c <= 255 for c in p.target_rgb):
                raise UserError(f"{self.name}: target_rgb needs 3 values in 0..255")
            self._target = color.from_rgb(p.target_rgb, p.target_noise_gray)
        self._pending: list[float] | None = None
        if p.seed_mode == "point":
            self._pending = self._checked_seed(p.seed_uv, "parameter seed_uv")
        elif p.seed_mode == "region":
            self._pending = self._checked_seed(p.seed_region, "parameter seed_region")
        self._frames = 0
        self._failures = 0
        self._snake_time = 0.0
        self._iterations = 0
        self._was_failed = False
        self._previous: np.ndarray | None = None
        self._identical = 0

    def retune(self, old: Parameters) -> None:
        """A tunable setting changed (tension, gate, step, iterations, adaptation): the tracker
        goes on with its contour and color model under the new settings."""
        self._tracker.params, self._tracker.limits = self._settings()

    def _frozen(self, pixels: np.ndarray) -> bool:
        """True when the last ``max_identical_frames`` images were identical: a live sensor always
        has noise, so a frame grabber that re-sends one buffer is caught even if it does not say
        so. Compares a fixed grid of 48 x 32 pixels, whatever the image size (cheap)."""
        limit = self.params.max_identical_frames
        if not limit:
            return False
        height, width = pixels.shape[:2]
        rows = np.linspace(0, height - 1, 32).astype(np.intp)
        cols = np.linspace(0, width - 1, 48).astype(np.intp)
        sample = pixels[rows[:, None], cols[None, :]]
        same = self._previous is not None and np.array_equal(sample, self._previous)
        self._previous = sample
        self._identical = self._identical + 1 if same else 0
        return self._identical >= limit

    def _checked_seed(self, values: list[float] | np.ndarray, where: str) -> list[float]:
        seed = [float(v) for v in np.asarray(values, dtype=float).ravel()]
        if len(seed) not in (2, 4) or not np.all(np.isfinite(seed)):
            raise UserError(
                f"{self.name}: {where} must be [u, v] or [u_min, v_min, u_max, v_max], got {seed}"
            )
        if len(seed) == 4 and (seed[2] <= seed[0] or seed[3] <= seed[1]):
            raise UserError(f"{self.name}: {where} is an empty region: {seed}")
        return seed

    def summary(self) -> dict[str, object]:
        frames = max(self._frames, 1)
        return {
            "frames": self._frames,
            "failures": self._failures,
            "snake_ms_mean": round(1e3 * self._snake_time / frames, 3),
            "iterations_mean": round(self._iterations / frames, 2),
        }

    def step(self, now: float) -> None:
        if self.seed.fresh and self.seed.value is not None:
            values = np.asarray(self.seed.value.values, dtype=float)
            try:
                self._pending = self._checked_seed(values, "input seed")
            except UserError as exc:
                self.log.warning("%s", exc)
        if not self.image.fresh:
            return
        sample = self.image.get(now)
        if sample is None:
            return
        if sample.stale:
            self.contour.send(_empty(FAILED, "camera image is stale", sample.stamp))
            return
        pixels = np.asarray(sample.pixels)  # the camera's frame, read in place (no copy)
        if pixels.dtype != np.uint8 or pixels.ndim not in (2, 3) or min(pixels.shape[:2]) < 2:
            raise UserError(
                f"{self.name}: images must be H x W x 3 uint8 BGR, got {pixels.shape} "
                f"{pixels.dtype}"
            )
        if pixels.ndim == 2 or pixels.shape[2] != 3:
            reason = f"grayscale image ({pixels.shape}): the snake tracks a colour, it needs BGR"
            self._fail(reason, sample.stamp)
            return
        if self._frozen(pixels):
            self._fail(
                f"camera frozen: {self._identical + 1} identical images in a row", sample.stamp
            )
            return
        if self._pending is not None:
            self._seed(pixels, self._pending)
            self._pending = None
        if not self._tracker.seeded:
            self.contour.send(_empty(IDLE, "waiting for a seed", sample.stamp))
            return
        update = self._tracker.update(pixels)
        self._frames += 1
        self._snake_time += update.snake_time_s
        self._iterations += update.iterations
        failed = update.status == FAILED
        if failed and not self._was_failed:
            self._failures += 1
            self.log.warning("%s: snake failed: %s", self.name, update.sanity.reason)
        self._was_failed = failed
        sanity = update.sanity
        self.contour.send(
            contour_message(
                update.vertices,
                sanity.features,
                sanity.status,
                sanity.reason,
                sample.stamp,
                sanity.offending,
            )
        )

    def _fail(self, reason: str, stamp: float) -> None:
        """Send a failed, empty contour (counted once per run of failures)."""
        if not self._was_failed:
            self._failures += 1
            self.log.warning("%s: snake failed: %s", self.name, reason)
        self._was_failed = True
        self.contour.send(_empty(FAILED, reason, stamp))

    def _seed(self, pixels: np.ndarray, seed: list[float]) -> None:
        try:
            if len(seed) == 2:
                self._tracker.seed_at_point(pixels, seed, self._target)
                return
            u0, v0, u1, v1 = seed
            model = self._target
            if model is None:
                centre = (0.5 * (u0 + u1), 0.5 * (v0 + v1))
                params = self._tracker.params
                model = color.fit(
                    seed_samples(pixels, centre, params.seed_radius_px), min_gray=params.min_gray
                )
            region = rectangle((0.5 * (u0 + u1), 0.5 * (v0 + v1)), (u1 - u0, v1 - v0))
            self._tracker.seed_with_region(region, model)
        except ValueError as exc:
            self.log.warning("%s: cannot seed at %s: %s", self.name, seed, exc)
            return
        self._was_failed = False


def _empty(status: str, reason: str, stamp: float) -> Contour:
    return contour_message(np.zeros((0, 2)), None, status, reason, stamp)
