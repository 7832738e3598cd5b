"""Files a graph names are checked before anything runs: what a module writes stays inside the
run folder, and a camera's video file must exist. ``umbra check`` says so at the parameter's
line, exit status 2, and nothing is written."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

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
