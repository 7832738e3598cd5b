"""Signal: a periodic test waveform (sine, square, triangle) or a step."""

from __future__ import annotations

import math
from typing import Literal

from umbra.connectors import Module, Output, Parameters, param
from umbra.connectors.messages import Scalar

#: Periodic waveforms as functions of the angle 2π f t + phase [rad]; values in [-1, 1].
PERIODIC = {
    "sine": math.sin,
    "square": lambda angle: 1.0 if math.sin(angle) >= 0 else -1.0,
    "triangle": lambda angle: 2 / math.pi * math.asin(math.sin(angle)),
}


class Signal(Module["Signal.Params"]):
    """offset + amplitude * waveform(2π f t + phase); ``step`` jumps from offset at ``t_step``."""

    class Params(Parameters):
        waveform: Literal["sine", "square", "triangle", "step"] = param("sine", "shape")
        amplitude: float = param(1.0, "peak deviation from the offset")
        frequency_hz: float = param(1.0, "frequency", unit="Hz", ge=0.0)
        phase: float = param(0.0, "phase", unit="rad")
        offset: float = param(0.0, "value around which it varies")
        t_step: float = param(0.0, "time of the step (waveform `step`)", unit="s", ge=0.0)
        noise_std: float = param(0.0, "standard deviation of added Gaussian noise", ge=0.0)

    output = Output(Scalar, doc="the waveform")

    def start(self) -> None:
        self._t0: float | None = None
        self._omega = 2 * math.pi * self.params.frequency_hz
        self._periodic = PERIODIC.get(self.params.waveform)  # None: the step

    def step(self, now: float) -> None:
        if self._t0 is None:
            self._t0 = now
        p = self.params
        t = now - self._t0
        if self._periodic is not None:
            shape = self._periodic(self._omega * t + p.phase)
        else:
            shape = 1.0 if t >= p.t_step else 0.0
        value = p.offset + p.amplitude * shape
        if p.noise_std:
            value += float(self.context.rng.normal(0.0, p.noise_std))
        self.output.send(Scalar(value=value))
