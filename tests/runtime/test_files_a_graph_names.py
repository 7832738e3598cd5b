"""Files a graph names are checked before anything runs: what a module writes stays inside the
run folder, and a camera's video file must exist. ``umbra check`` says so at the parameter's
line, exit status 2, and nothing is written."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from umbra.runtime.cli.main import main

GRAPH = """graph: files
modules:
  cam: {{type: DigiCam, rate: 10, params: {{source: {source}}}}}
  view: {{type: Overlay, params: {{video: {video}}}}}
  plot: {{type: StatusPlot, params: {{path: {plot}}}}}
  servo: {{type: vsServo}}
  snake: {{type: vsSnake}}
connections:
  - cam.image -> view.image
  - cam.image -> snake.image
  - snake.contour -> servo.contour
  - servo.status -> plot.status
"""


def check(tmp_path: Path, **values: str) -> subprocess.CompletedProcess:
    fields = {"source": "sim", "video": "view.avi", "plot": "plot.png", **values}
    graph = tmp_path / "files.yaml"
    graph.write_text(GRAPH.format(**fields))
    return subprocess.run(
        [sys.executable, "-m", "umbra.runtime.cli.main", "check", str(graph)],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )


def test_a_sound_graph_checks(tmp_path: Path) -> None:
    (tmp_path / "clip.avi").write_bytes(b"x")
    proc = check(tmp_path, source="clip.avi", video="videos/view.mp4", plot="plots/p.png")
    assert proc.returncode == 0, proc.stderr


def test_written_files_stay_in_the_run_folder(tmp_path: Path) -> None:
    outside = tmp_path / "escaped.avi"
    proc = check(tmp_path, video=str(outside), plot="../up.png")
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert any(":4:" in ln and "`video` of `view`" in ln and "absolute" in ln for ln in lines)
    assert any(
        ":5:" in ln and "`path` of `plot`" in ln and "leaves the run folder" in ln for ln in lines
    )
    assert "Traceback" not in proc.stderr
    assert not outside.exists()


def test_the_video_container_is_known_before_the_run(tmp_path: Path) -> None:
    proc = check(tmp_path, video="view.xyz")
    assert proc.returncode == 2
    assert "expected a file ending in .avi or .mp4, found 'view.xyz'" in proc.stderr


def test_a_missing_camera_file_is_a_check_error(tmp_path: Path) -> None:
    proc = check(tmp_path, source="missing_clip.avi")
    assert proc.returncode == 2
    assert (
        ":3:" in proc.stderr
        and "video file missing_clip.avi not found (no such file" in proc.stderr
    )


RECORDER = """graph: rec
modules:
  src: {{type: Counter, rate: 20}}
  rec: {{type: Recorder, params: {{channels: [count], path: {path}}}}}
connections:
  - src.count -> rec.count
"""


def _run(tmp_path: Path, path: str, *extra: str) -> int:
    graph = tmp_path / "rec.yaml"
    graph.write_text(RECORDER.format(path=path))
    return main(["run", str(graph), "--single-process", "--clock", "sim", "--duration", "0.5",
                 "--quiet", "--out", str(tmp_path / "out"), *extra])  # fmt: skip


def test_a_recorder_outside_the_run_folder_is_refused_in_the_graph(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    for path, why in ((str(tmp_path / "outside.mcap"), "is absolute"), ("../up.mcap", "leaves")):
        assert _run(tmp_path, path) == 2
        first = capsys.readouterr().err.splitlines()[0]
        assert first.startswith(f"{tmp_path / 'rec.yaml'}:4:") and why in first
        assert "name an outside file on the command line" in first
        assert not (tmp_path / "out").exists() and not (tmp_path / "outside.mcap").exists()


def test_the_user_names_an_outside_file_on_the_command_line(tmp_path: Path) -> None:
    outside = tmp_path / "elsewhere" / "pick.mcap"
    assert _run(tmp_path, "rec.mcap", "--set", f"rec.path={outside}") == 0
    assert outside.stat().st_size > 1000 and not (tmp_path / "out" / "rec.mcap").exists()
    assert _run(tmp_path, "rec.mcap", "--set", "rec.path=../beside.mcap") == 0
    assert (tmp_path / "beside.mcap").stat().st_size > 1000
