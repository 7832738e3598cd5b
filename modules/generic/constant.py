"""Constant sources: a scalar, or a twist in a named frame."""

from __future__ import annotations

import numpy as np

from umbra.connectors import Module, Output, Parameters, from_param, param
from umbra.connectors.messages import Scalar, Twist


class Constant(Module["Constant.Params"]):
    """Sends the same scalar every period."""

    class Params(Parameters):
        value: float = param(0.0, "the value sent")

    output = Output(Scalar, doc="the constant")

    def start(self) -> None:
        self._sample = Scalar(value=self.params.value)

    def step(self, now: float) -> None:
        self.output.send(self._sample)  # send stamps a copy; the unstamped template stays


class TwistSource(Module["TwistSource.Params"]):
    """Sends a constant twist [vx, vy, vz, wx, wy, wz] (m/s, rad/s) in frame ``frame``."""

    class Params(Parameters):
        twist: list[float] = param(
            [0.0] * 6, "twist [vx vy vz wx wy wz]", unit="m/s, rad/s", min_length=6, max_length=6
        )
        frame: str = param("camera", "frame the twist is expressed in")

    twist = Output(Twist, frame=from_param("frame"), doc="the constant twist")

    def start(self) -> None:
        vector = np.asarray(self.params.twist, dtype=float)
        self._sample = Twist(vector=vector, frame=self.params.frame)

    def step(self, now: float) -> None:
        self.twist.send(self._sample)
