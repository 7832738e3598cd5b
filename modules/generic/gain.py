"""Gain: scales a scalar (the smallest useful transform, for chains and tests)."""

from __future__ import annotations

from umbra.connectors import Input, Module, Output, Parameters, param
from umbra.connectors.messages import Scalar


class Gain(Module["Gain.Params"]):
    """output = gain * input + bias, on every new input."""

    class Params(Parameters):
        gain: float = param(1.0, "factor", tunable=True)
        bias: float = param(0.0, "added after scaling", tunable=True)

    input = Input(Scalar, trigger=True, doc="value to scale")
    output = Output(Scalar, doc="scaled value")

    def step(self, now: float) -> None:
        sample = self.input.get(now)
        if sample is not None and self.input.fresh:
            p = self.params
            self.output.send(Scalar(value=p.gain * sample.value + p.bias, stamp=sample.stamp))
