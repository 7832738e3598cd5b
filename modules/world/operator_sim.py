"""OperatorSim: a simulated operator who clicks on the patch to seed the snake.

In the seeds the operator starts a grab by clicking on the colored patch in the live video. In a
simulation the camera knows where the patch is (its ``truth`` output); this module "clicks" there,
with a little hand jitter, once the image has been on screen for ``click_delay_s``. It never
answers an assistance request: a stopped grab stays stopped, which is what the safety trials
measure. With an operator console (``console`` input, its ``presence`` output), it steps aside
for good the moment a person takes control, and does not click after that. In an attended run
(``umbra run --attended``: ``ModuleContext.attended``) it never clicks at all.
"""

from __future__ import annotations

import numpy as np

from umbra.connectors import Input, Module, Output, Parameters, param
from umbra.connectors.commands import Seed
from umbra.connectors.messages import Contour
from umbra.connectors.states import Presence


class OperatorSim(Module["OperatorSim.Params"]):
    """Clicks on the patch (seed point for vsSnake) from the simulated camera's ground truth."""

    class Params(Parameters):
        click_delay_s: float = param(
            0.2, "time looking at the video before clicking", unit="s", ge=0
        )
        click_noise_px: float = param(
            2.0, "standard deviation of the click position", unit="px", ge=0
        )

    truth = Input(Contour, trigger=True, doc="patch outline in the image (sim camera truth)")
    console = Input(
        Presence, required=False, doc="the console's presence: a person acted -> step aside"
    )
    seed = Output(Seed, events=True, doc="the click: a point seed [u, v] px for vsSnake")

    def start(self) -> None:
        self._started: float | None = None  # clock time [s] of the first step
        self._first_seen: float | None = None
        self.clicked_at: float | None = None
        self.click: list[float] = []
        self.stepped_aside_at: float | None = None
        if self.context.attended:
            self.log.info("attended run: the simulated operator stays off (a person seeds)")

    def step(self, now: float) -> None:
        if self._started is None:
            self._started = now
        if self.stepped_aside_at is not None or self.context.attended:
            return
        console = self.console.get(now)
        if console is not None and (console.person or console.acted):
            self.stepped_aside_at = now  # also after its click: the person answers from now on
            self.log.info(
                "a person took control of the console: the simulated operator steps aside"
            )
            return
        if self.clicked_at is not None:
            return
        truth = self.truth.get(now)
        if truth is None or truth.area <= 0:
            return
        if self._first_seen is None:
            self._first_seen = now
        if now - self._first_seen < self.params.click_delay_s:
            return
        jitter = self.context.rng.normal(0.0, self.params.click_noise_px, 2)
        uv = np.asarray(truth.centroid, dtype=float) + jitter
        self.seed.send(Seed.point(float(uv[0]), float(uv[1])))
        self.clicked_at = now
        self.click = [round(float(v), 2) for v in uv]
        self.log.info("operator clicked the patch at (%.1f, %.1f) px", uv[0], uv[1])

    def summary(self) -> dict[str, object]:
        """``clicked_after_s``: seconds from the module's first step to the click (None: no
        click); ``clicked_at_s``: the clock time of the click [s], comparable with the other
        modules' clock times (a fault's start, say); ``click_uv``: where it clicked [px];
        ``stepped_aside_at_s``: when a person took over (None: never); ``attended``: the run
        was attended, so it stayed off."""
        after = None
        if self.clicked_at is not None and self._started is not None:
            after = round(self.clicked_at - self._started, 3)
        return {
            "clicked_after_s": after,
            "clicked_at_s": self.clicked_at,
            "click_uv": self.click,
            "stepped_aside_at_s": self.stepped_aside_at,
            "attended": self.context.attended,
        }
