"""The graph's ``record:`` setting and the Recorder's path: checked with file:line, exit 2."""

from __future__ import annotations

from pathlib import Path

import pytest

from umbra.runtime.cli.main import main

GRAPH = """graph: g
clock: sim
{record}
modules:
  c: {{type: Counter, rate: 10}}
  rec: {{type: Recorder, params: {{channels: [x], path: {path}}}}}
connections: [c.count -> rec.x]
"""


def _check(tmp_path: Path, capsys: pytest.CaptureFixture[str], **parts: str) -> tuple[int, str]:
    graph = tmp_path / "g.yaml"
    graph.write_text(GRAPH.format(**{"record": "", "path": "r.mcap", **parts}))
    code = main(["check", str(graph)])
    return code, capsys.readouterr().err.replace(str(graph), "G")


@pytest.mark.parametrize(
    ("record", "expected"),
    [
        ("record: {images: gif}", "G:3:18: error: `record.images` must be one of raw, jpeg, png"),
        ("record: {jpeg_quality: 0}", "G:3:24: error: `record.jpeg_quality` must be a whole"),
        ("record: {ports: {c.count: loud}}", "G:3:27: error: `record.ports.c.count` must be one"),
        ("record: {ports: {nope.x: raw}}", "G:3:18: error: `record.ports`: no module `nope`"),
        (
            "record: {ports: {c.cnt: raw}}",
            "G:3:18: error: `record.ports`: module `c` has no output",
        ),
        ("record: {file: ../up.mcap}", "G:3:16: error: `record.file` '../up.mcap' leaves the run"),
        ("record: {speed: 2}", "G:3:10: error: unknown key `speed` in `record`"),
        ("record: 3", "G:3:9: error: `record` must be true, false or a mapping"),
    ],
)
def test_bad_record_settings_are_check_errors_at_their_place(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], record: str, expected: str
) -> None:
    code, err = _check(tmp_path, capsys, record=record)
    assert code == 2 and expected in err, err


@pytest.mark.parametrize(
    ("path", "why"),
    [("../outside.mcap", "leaves the run folder"), ("/tmp/abs.mcap", "is absolute")],
)
def test_a_recorder_path_outside_the_run_folder_is_a_check_error_at_its_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], path: str, why: str
) -> None:
    code, err = _check(tmp_path, capsys, path=path)
    assert code == 2 and "G:6:" in err and why in err and "Traceback" not in err


def test_good_settings_check_and_record_images_needs_record(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, err = _check(
        tmp_path, capsys, record="record: {images: png, ports: {c.count: off}}", path="sub/r.mcap"
    )
    assert code == 0, err
    graph = tmp_path / "plain.yaml"
    graph.write_text(GRAPH.format(record="", path="r.mcap"))
    code = main(["run", str(graph), "--record-images", "raw", "--out", str(tmp_path / "o")])
    assert code == 2 and "--record-images needs --record" in capsys.readouterr().err


def test_a_recorder_writing_the_runs_recording_file_is_refused_at_its_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    graph = tmp_path / "g.yaml"
    graph.write_text(GRAPH.format(record="record: true", path="recording.mcap"))
    code = main(["run", str(graph), "--duration", "0.5", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 2 and f"{graph}:6:" in err and "module `rec` writes `recording.mcap`" in err
    assert not (tmp_path / "o" / "recording.mcap").exists()
