"""Generic modules through the public harness — the way users test their own modules."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from connectors.errors import UserError
from connectors.messages import Image, JointState, Scalar, Status, Twist
from modules.generic.recording import read_recording
from runtime.harness import ModuleHarness


def test_gain_scales_each_new_input() -> None:
    with ModuleHarness("Gain", {"gain": 3.0, "bias": 1.0}) as h:
        h.push("input", Scalar(value=2.0))
        sent = h.step(0.01)
        assert [s.value for s in sent["output"]] == [7.0]
        assert h.step(0.01) == {}  # nothing new: gain is triggered, not periodic


def test_counter_counts_and_stops() -> None:
    with ModuleHarness("Counter", {"start": 5, "step_by": 2, "stop_after": 3}) as h:
        h.run(3, 0.1)
        assert [s.value for s in h.outputs("count")] == [5.0, 7.0, 9.0]
        assert [s.seq for s in h.outputs("count")] == [1, 2, 3]
        assert h.stop_request == ("`module` sent 3 values", 0)


@pytest.mark.parametrize(
    ("waveform", "t", "expected"),
    [
        ("sine", 0.25, 2.0 + 3.0),
        ("square", 0.75, 2.0 - 3.0),
        ("triangle", 0.25, 5.0),
        ("step", 0.3, 5.0),
        ("step", 0.1, 2.0),
    ],
)
def test_signal_waveforms(waveform: str, t: float, expected: float) -> None:
    params = {
        "waveform": waveform,
        "amplitude": 3.0,
        "offset": 2.0,
        "frequency_hz": 1.0,
        "t_step": 0.2,
    }
    with ModuleHarness("Signal", params) as h:
        h.step(0.0)
        h.step(t)
        assert h.output("output").value == pytest.approx(expected, abs=1e-9)


def test_twist_source_frame_from_parameter() -> None:
    with ModuleHarness("TwistSource", {"twist": [0.1, 0, 0, 0, 0, 0.2], "frame": "tool"}) as h:
        h.step(0.01)
        twist = h.output("twist")
        assert twist.frame == "tool" and np.allclose(twist.vector, [0.1, 0, 0, 0, 0, 0.2])


def test_bad_parameters_are_a_user_error() -> None:
    with pytest.raises(UserError, match="max_rate_hz"):
        ModuleHarness("Printer", {"max_rate_hz": 0})
    with pytest.raises(UserError, match="unknown module type `Gian`; did you mean `Gain`"):
        ModuleHarness("Gian")


def test_printer_prints_rate_limited(capsys) -> None:
    with ModuleHarness("Printer", {"max_rate_hz": 2.0}, name="p") as h:
        for k in range(10):
            h.push("value", Scalar(value=float(k)))
            h.step(0.1)
    lines = capsys.readouterr().out.splitlines()
    # steps at 0.1 .. 1.0 s, at most 2 lines per second: printed at 0.1 and 0.6 s
    assert lines == ["[p] t=0.000 Scalar(seq=1, value=0)", "[p] t=0.500 Scalar(seq=6, value=5)"]
    assert h.module.summary() == {"seen": 10, "printed": 2}


def test_recorder_writes_mcap_that_reads_back(tmp_path: Path) -> None:
    pixels = np.random.default_rng(0).integers(0, 255, (48, 64, 3), dtype=np.uint8)
    samples = {
        "twist": Twist(vector=np.arange(6.0), frame="camera"),
        "image": Image(pixels=pixels),
        "status": Status(stage="approach", values={"ex": 0.5}),
        "joints": JointState(names=("j1", "j2"), position=np.array([0.1, -0.2])),
    }
    with ModuleHarness(
        "Recorder", {"channels": list(samples), "path": "r/x.mcap"}, output_dir=tmp_path
    ) as h:
        for name, sample in samples.items():
            h.push(name, sample)
        h.step(0.5)
        h.push("twist", Twist(vector=np.ones(6), frame="camera"))
        h.step(0.5)
    back = list(read_recording(tmp_path / "r" / "x.mcap"))
    assert [c for c, _ in back] == [*samples, "twist"]
    by_channel = dict(back[:4])
    assert np.array_equal(by_channel["image"].pixels, pixels)
    assert by_channel["status"].values == {"ex": 0.5}
    assert by_channel["joints"].names == ("j1", "j2")
    assert back[4][1].seq == 2 and math.isclose(back[4][1].stamp, 0.5)


def test_reading_a_non_recording_is_a_user_error(tmp_path: Path) -> None:
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"not an mcap file at all")
    with pytest.raises(UserError, match="error: not an MCAP file"):
        list(read_recording(junk))
