"""Constant sources: a scalar, or a twist in a named frame."""

from __future__ import annotations

import numpy as np

from connectors import Module, Output, Parameters, from_param, param
from connectors.messages import Scalar, Twist


class Constant(Module):
    """Sends the same scalar every period."""

    class Params(Parameters):
        value: float = param(0.0, "the value sent")

    output = Output(Scalar, doc="the constant")

    def step(self, now: float) -> None:
        self.output.send(Scalar(value=self.params.value))


class TwistSource(Module):
    """Sends a constant twist [vx, vy, vz, wx, wy, wz] (m/s, rad/s) in frame ``frame``."""

    class Params(Parameters):
        twist: list[float] = param(
            [0.0] * 6, "twist [vx vy vz wx wy wz]", unit="m/s, rad/s", min_length=6, max_length=6
        )
        frame: str = param("camera", "frame the twist is expressed in")

    twist = Output(Twist, frame=from_param("frame"), doc="the constant twist")

    def start(self) -> None:
        self._vector = np.asarray(self.params.twist, dtype=float)

    def step(self, now: float) -> None:
        self.twist.send(Twist(vector=self._vector, frame=self.params.frame))
