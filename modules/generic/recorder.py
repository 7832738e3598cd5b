"""Recorder: writes chosen connectors to an MCAP file that ``read_recording`` reads back."""

from __future__ import annotations

from connectors import Input, Module, Parameters, param
from connectors.messages import Message
from modules.generic.recording import RecordingWriter


class Recorder(Module):
    """Records every new sample on each of its ``channels`` inputs.

    The inputs are named by the ``channels`` parameter (``channels: [twist, status]`` gives inputs
    ``twist`` and ``status``, each accepting any message type). The file is finished when the run
    stops for any reason, so a stopped run keeps its recording.
    """

    class Params(Parameters):
        channels: list[str] = param(["input"], "names of the inputs to record", min_length=1)
        path: str = param("recording.mcap", "output file, relative to the run's output folder")

    @classmethod
    def dynamic_inputs(cls, params: Parameters) -> dict[str, Input]:
        return {
            name: Input(Message, trigger=True, required=False, doc=f"recorded as `{name}`")
            for name in params.channels  # type: ignore[attr-defined]
        }

    def start(self) -> None:
        path = self.context.output_dir / self.params.path
        path.parent.mkdir(parents=True, exist_ok=True)
        self.path = path
        self._writer = RecordingWriter(path)

    def step(self, now: float) -> None:
        for name, reg in self.registers.items():
            if reg.fresh and reg.value is not None:
                self._writer.write(name, reg.value)

    def stop(self) -> None:
        self._writer.close()

    def summary(self) -> dict[str, object]:
        return {"recorded": self._writer.count, "file": str(self.path)}
