"""vsSnake: the statistical pressure snake as a module: image in, tracked contour out."""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import model_validator

from umbra.connectors import Input, Module, Output, Parameters, UserError, param
from umbra.connectors.commands import Seed
from umbra.connectors.messages import Contour, Image
from umbra.connectors.params import Channel, ParamProblem
from umbra.connectors.tracking import SnakeCheck, TrackStatus
from umbra.modules.vision import color
from umbra.modules.vision.contour_message import contour_message
from umbra.modules.vision.polygon import rectangle
from umbra.modules.vision.sanity import FAILED
from umbra.modules.vision.snake import seed_samples
from umbra.modules.vision.snake_config import SnakeSettings, snake_setup
from umbra.modules.vision.tracker import IDLE, SnakeTracker


class VsSnake(Module["VsSnake.Params"]):
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

    class Params(SnakeSettings):
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
        target_rgb: list[Channel] = param(
            [],
            "target color RGB 0..255 for region seeds (empty: learn it at the region centre)",
            max_length=3,
        )
        target_noise_gray: float = param(
            8.0, "spread of the target_rgb color model", unit="gray levels", gt=0
        )
        max_identical_frames: int = param(
            5, "this many identical images in a row mean a frozen camera (0: never)", ge=0
        )

        @model_validator(mode="after")
        def _seeds(self) -> VsSnake.Params:
            """A target color has its 3 channels; a region seed is not empty."""
            if len(self.target_rgb) not in (0, 3):
                raise ParamProblem(
                    "target_rgb", f"needs 3 values in 0..255 (or none), found {self.target_rgb}"
                )
            u0, v0, u1, v1 = self.seed_region
            if self.seed_mode == "region" and (u1 <= u0 or v1 <= v0):
                raise ParamProblem(
                    "seed_region",
                    f"is an empty region: expected u_min < u_max and v_min < v_max, "
                    f"found {self.seed_region}",
                )
            return self

    image = Input(Image, trigger=True, doc="camera frames (BGR)")
    seed = Input(Seed, required=False, doc="operator re-seed: a point or a box, px")
    contour = Output(
        Contour, origin_from=("image",), doc="tracked contour, features and sanity status"
    )

    def start(self) -> None:
        p = self.params
        self._tracker = SnakeTracker(*snake_setup(p))
        self._target = None
        if p.target_rgb:
            self._target = color.from_rgb(p.target_rgb, p.target_noise_gray)
        self._pending: list[float] | None = None
        if p.seed_mode == "point":
            self._pending = [float(v) for v in p.seed_uv]
        elif p.seed_mode == "region":
            self._pending = [float(v) for v in p.seed_region]
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
        self._tracker.params, self._tracker.limits = snake_setup(self.params)

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
            seed = self.seed.value
            problem = seed.problem()
            if problem:
                self.log.warning("%s: input seed refused: %s", self.name, problem)
            else:
                self._pending = [float(v) for v in np.asarray(seed.uv, dtype=float)]
        if not self.image.fresh:
            return
        sample = self.image.get(now)
        if sample is None:
            return
        if sample.stale:
            self.contour.send(
                _empty(FAILED, "camera image is stale", sample.stamp, (SnakeCheck.STALE_IMAGE,))
            )
            return
        pixels = np.asarray(sample.pixels)  # the camera's frame, read in place (no copy)
        if pixels.dtype != np.uint8 or pixels.ndim not in (2, 3) or min(pixels.shape[:2]) < 2:
            raise UserError(
                f"{self.name}: images must be H x W x 3 uint8 BGR, got {pixels.shape} "
                f"{pixels.dtype}"
            )
        if pixels.ndim == 2 or pixels.shape[2] != 3:
            reason = f"grayscale image ({pixels.shape}): the snake tracks a colour, it needs BGR"
            self._fail(reason, sample.stamp, SnakeCheck.GRAYSCALE_IMAGE)
            return
        if self._frozen(pixels):
            self._fail(
                f"camera frozen: {self._identical + 1} identical images in a row",
                sample.stamp,
                SnakeCheck.CAMERA_FROZEN,
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
                sanity.checks,
            )
        )

    def _fail(self, reason: str, stamp: float, check: SnakeCheck) -> None:
        """Send a failed, empty contour (counted once per run of failures)."""
        if not self._was_failed:
            self._failures += 1
            self.log.warning("%s: snake failed: %s", self.name, reason)
        self._was_failed = True
        self.contour.send(_empty(FAILED, reason, stamp, (check,)))

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


def _empty(
    status: TrackStatus, reason: str, stamp: float, checks: tuple[SnakeCheck, ...] = ()
) -> Contour:
    return contour_message(np.zeros((0, 2)), None, status, reason, stamp, checks=checks)
