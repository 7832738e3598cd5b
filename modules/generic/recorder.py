"""Recorder: writes chosen connectors to an MCAP file that ``read_recording`` reads back."""

from __future__ import annotations

from pydantic import field_validator

from umbra.connectors import Input, Module, Parameters, param
from umbra.connectors.messages import Message
from umbra.connectors.params import RunFile
from umbra.modules.generic.recording import RecordingWriter
from umbra.runtime.recording.settings import IMAGE_CHOICES


class Recorder(Module["Recorder.Params"]):
    """Records every new sample on each of its ``channels`` inputs.

    The inputs are named by the ``channels`` parameter (``channels: [twist, status]`` gives inputs
    ``twist`` and ``status``, each accepting any message type). Samples are encoded for viewers
    (``umbra.runtime.recording``) and written from the recorder's own thread: on the real clock a
    full queue drops (and counts) samples rather than holding the tick. The file is finished when
    the run stops for any reason, so a stopped run keeps its recording. To record every connection
    of a run, use ``umbra run --record`` instead.
    """

    class Params(Parameters):
        channels: list[str] = param(["input"], "names of the inputs to record", min_length=1)
        path: RunFile = param(
            "recording.mcap",
            "output file, inside the run's output folder (outside it only from the command line)",
            min_length=1,
        )
        images: str = param("raw", "how images are recorded: raw, jpeg or png")

        @field_validator("images")
        @classmethod
        def _images(cls, value: str) -> str:
            if value not in IMAGE_CHOICES:
                raise ValueError(f"images must be one of {', '.join(IMAGE_CHOICES)}")
            return value

    @classmethod
    def dynamic_inputs(cls, params: Parameters) -> dict[str, Input]:
        return {
            name: Input(Message, trigger=True, required=False, doc=f"recorded as `{name}`")
            for name in params.channels  # type: ignore[attr-defined]
        }

    def start(self) -> None:
        self.path = self.context.output_dir / self.params.path
        self._writer = RecordingWriter(
            self.path, blocking=self.context.clock == "sim", images=self.params.images
        )

    def step(self, now: float) -> None:
        for name, reg in self.registers.items():
            if reg.fresh and reg.value is not None:
                self._writer.write(name, reg.value, now)

    def stop(self) -> None:
        self._writer.close()

    def summary(self) -> dict[str, object]:
        return {
            "recorded": self._writer.count,
            "dropped": self._writer.dropped,
            "file": str(self.path),
        }
