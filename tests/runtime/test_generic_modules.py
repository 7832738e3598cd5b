"""Generic modules through the public harness — the way users test their own modules."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from umbra.connectors.errors import UserError
from umbra.connectors.messages import Image, JointState, Scalar, Status, Twist
from umbra.modules.generic.recording import read_recording
from umbra.runtime.harness import ModuleHarness


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
        for k in range(100):
            h.push("value", Scalar(value=float(k)))
            h.step(0.1)
    lines = capsys.readouterr().out.splitlines()
    # 10 s of samples at 10 Hz, at most 2 lines per second in the long run
    printed = [float(line.rsplit("value=", 1)[1].rstrip(")")) for line in lines]
    assert lines[0].startswith("[p] t=0.000 Scalar(seq=1")
    assert printed[:3] == [0.0, 3.0, 8.0]  # credit 1 at start, then one line per 0.5 s
    assert h.module.summary() == {"seen": 100, "printed": len(lines)}
    assert 20 <= len(lines) <= 21


@pytest.mark.parametrize("jitter", [0.0, 0.3])
def test_printer_fed_at_its_rate_prints_every_sample(capsys, jitter: float) -> None:
    """10 Hz into a 10 Hz Printer: all 50 samples printed, on steps whose spacing rounds just
    under 0.1 s (0.7 - 0.6) or jitters by 30 % of the period."""
    with ModuleHarness("Printer", {"max_rate_hz": 10.0}, name="p") as h:
        for k in range(50):
            h.push("value", Scalar(value=float(k)))
            h.step(0.1 + (jitter * 0.1 * (1 if k % 2 else -1) if jitter else 0.0))
    assert h.module.summary() == {"seen": 50, "printed": 50}
    assert len(capsys.readouterr().out.splitlines()) == 50


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


def test_required_parameters_are_described_and_named_when_missing() -> None:
    from umbra.connectors import Module, Parameters, param
    from umbra.runtime.cli.cmd_describe import describe

    class Needs(Module):
        """Needs a gain."""

        class Params(Parameters):
            gain: float = param(..., "factor, no default", gt=0)
            bias: float = param(0.0, "added")

    text = describe(Needs)
    assert "gain: float (required), > 0  factor, no default" in text
    assert "PydanticUndefined" not in text and "bias: float = 0.0" in text
    with pytest.raises(UserError) as caught:
        ModuleHarness(Needs, {"bias": True, "nope": 1})
    message = str(caught.value)
    assert "parameter `gain` is required and was not given" in message
    assert "unknown parameter `nope` (parameters: gain, bias)" in message
    assert "parameter `bias`: expected a number, found a boolean" in message
    assert "pydantic" not in message and "validation error" not in message


def test_umbra_modules_prints_whole_first_sentences() -> None:
    from umbra.runtime.cli.cmd_modules import first_sentence

    assert first_sentence("Moves a pose: ``T = T_a . T_b``.\n\nMore.") == (
        "Moves a pose: ``T = T_a . T_b``."
    )
    assert first_sentence("A web page (127.0.0.1 by\ndefault) with video. Then more.") == (
        "A web page (127.0.0.1 by default) with video."
    )
    assert first_sentence("Speed 0.5 m/s, e.g. slow") == "Speed 0.5 m/s, e.g. slow"
