"""A real graph on the real scheduler: simulated DigiCam -> vsSnake -> Overlay (with video)."""

from __future__ import annotations

import cv2

from umbra.modules.vision.digicam import DigiCam
from umbra.modules.vision.overlay_module import Overlay
from umbra.modules.vision.vs_snake import VsSnake
from umbra.runtime.graph.check import check_text
from umbra.runtime.registry import Registry
from umbra.runtime.scheduler import Scheduler, SchedulerOptions

GRAPH = """\
graph: vision
seed: 1
clock: sim
modules:
  cam: {type: DigiCam, rate: 30, params: {noise_sigma: 6, patch_yaw_deg: 20, background: photo}}
  snake: {type: vsSnake, params: {seed_uv: [322, 236]}}
  view: {type: Overlay, params: {video: view.avi, video_fps: 30}}
connections:
  - cam.image -> snake.image
  - cam.image -> view.image
  - snake.contour -> view.contour
"""


def test_camera_snake_overlay_graph(tmp_path) -> None:
    registry = Registry()
    for cls in (DigiCam, VsSnake, Overlay):
        registry.add(cls)
    plan = check_text(GRAPH, "vision.yaml", registry)
    scheduler = Scheduler(plan, SchedulerOptions(clock="sim", duration=1.0, output_dir=tmp_path))
    scheduler.run()
    snake = scheduler.modules["snake"]
    summary = snake.summary()
    assert summary["frames"] >= 29 and summary["failures"] == 0
    last = snake.contour.last
    assert last.status == "tracking"
    assert abs(last.area - 17851) / 17851 < 0.05  # 0.06 x 0.04 m at 0.22 m, f = 600 px
    view = scheduler.modules["view"].summary()
    assert view["frames"] == summary["frames"]
    capture = cv2.VideoCapture(str(tmp_path / "view.avi"))
    count = 0
    while capture.read()[0]:
        count += 1
    assert count == view["video_frames"] == summary["frames"]
