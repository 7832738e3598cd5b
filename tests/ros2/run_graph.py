"""A run whose camera is published to ROS 2 and whose snake takes its images from ROS 2: a sim
DigiCam's frames go out on ``/wrist_camera/image_raw``, a ROS 2 camera's come in on
``/camera/image_raw`` and the snake's contour made from them goes out on ``/snake/contour``."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

#: ``PROCESS_CAM`` / ``PROCESS_SNAKE``: where the camera and the snake run.
GRAPH = """\
graph: r2run
clock: real
processes: PROCESSES
modules:
  cam:
    type: DigiCam
    PROCESS_CAM
    rate: 10
    params: {source: sim, width: 640, height: 480, fx: 500, fy: 500, u0: 320, v0: 240}
  snake: {type: vsSnake, PROCESS_SNAKE params: {seed_mode: none}}
connections: []
ros2:
  out:
    cam.image: {topic: /wrist_camera/image_raw, type: sensor_msgs/msg/Image}
    snake.contour: {topic: /snake/contour, type: geometry_msgs/msg/PolygonStamped}
  in:
    snake.image: {topic: /camera/image_raw, type: sensor_msgs/msg/Image, clock_error_s: 0.001}
"""


def write_graph(folder: Path, split: bool = False) -> Path:
    """The graph in ``folder``: one process, or the camera in `vision` and the snake in `track`."""
    text = GRAPH.replace("PROCESSES", "{vision: {}, track: {}}" if split else "{}")
    text = text.replace("PROCESS_CAM", "process: vision" if split else "")
    text = text.replace("PROCESS_SNAKE", "process: track," if split else "")
    path = folder / "r2run.yaml"
    path.write_text(text)
    return path


def start_run(graph: Path, out: Path, *args: str) -> subprocess.Popen[str]:
    """``umbra run GRAPH --out OUT ARGS`` in a child process (stdout and stderr piped)."""
    root = str(Path(__file__).resolve().parents[2])
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    env["PYTHONPATH"] = os.pathsep.join(p for p in (root, env.get("PYTHONPATH", "")) if p)
    return subprocess.Popen(
        [
            sys.executable,
            "-m",
            "umbra.runtime.cli.main",
            "run",
            str(graph),
            "--out",
            str(out),
            *list(args),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
