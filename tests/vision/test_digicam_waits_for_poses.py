"""A simulated camera whose poses are wired renders nothing until they arrive: a frame made from
the parameters' stand-in pose would show the patch where it is not (an operator, or OperatorSim,
clicking it seeds the snake on the table)."""

from __future__ import annotations

from pathlib import Path
from typing import ClassVar

import numpy as np

from umbra.connectors import Input, Module, Output, Parameters, param
from umbra.connectors.messages import Contour, Pose
from umbra.modules.vision.digicam import DigiCam
from umbra.modules.vision.scene import camera_looking_down, pose
from umbra.runtime.graph.check import check_text
from umbra.runtime.harness import ModuleHarness
from umbra.runtime.registry import Registry
from umbra.runtime.scheduler import Scheduler, SchedulerOptions

#: Where the patch really is [m], away from where the camera's stand-in pose would put it.
T_WORLD_PATCH = pose((0.05, -0.03, 0.0), 0.4)
T_WORLD_CAMERA = camera_looking_down((0.0, 0.0, 0.0), 0.35)


def test_a_wired_pose_that_has_not_come_yet_holds_the_first_frame() -> None:
    with ModuleHarness(DigiCam, {"source": "sim"}) as cam:
        cam.module.registers["camera_pose"].connected = True  # wired, nothing sent yet
        assert not cam.step(0.1).get("image")
        cam.push("camera_pose", Pose(matrix=T_WORLD_CAMERA, parent="world", child="camera"))
        assert len(cam.step(0.1)["image"]) == 1


def test_unwired_poses_are_stood_in_by_the_parameters() -> None:
    with ModuleHarness(DigiCam, {"source": "sim"}) as cam:
        assert len(cam.step(0.1)["image"]) == 1


class LatePoses(Module):
    """The world's poses, first sent at ``start_s``."""

    class Params(Parameters):
        start_s: float = param(0.5, "first pose at", unit="s")

    camera_pose = Output(Pose, measured=True)
    patch_pose = Output(Pose, measured=True)

    def step(self, now: float) -> None:
        if now >= self.params.start_s:
            self.camera_pose.send(Pose(matrix=T_WORLD_CAMERA, parent="world", child="camera"))
            self.patch_pose.send(Pose(matrix=T_WORLD_PATCH, parent="world", child="patch"))


class FirstTruth(Module):
    """Keeps the first ground-truth outline the camera sends, and when."""

    seen: ClassVar[list[tuple[float, np.ndarray]]] = []

    truth = Input(Contour, trigger=True)

    def step(self, now: float) -> None:
        sample = self.truth.get(now)
        if sample is not None and self.truth.fresh:
            FirstTruth.seen.append((now, np.asarray(sample.centroid, dtype=float)))


GRAPH = """
graph: late_poses
clock: sim
modules:
  world: {type: LatePoses, rate: 100}
  camera: {type: DigiCam, rate: 30, params: {source: sim, world_frame: world}}
  probe: {type: FirstTruth}
connections:
  - world.camera_pose -> camera.camera_pose
  - world.patch_pose -> camera.patch_pose
  - camera.truth -> probe.truth
"""


def test_in_a_graph_the_first_frame_shows_the_patch_where_the_world_has_it(
    tmp_path: Path,
) -> None:
    FirstTruth.seen = []
    registry = Registry()
    for cls in (LatePoses, FirstTruth, DigiCam):
        registry.add(cls)
    plan = check_text(GRAPH, "g.yaml", registry)
    Scheduler(plan, SchedulerOptions(duration=1.0, output_dir=tmp_path)).run()
    assert FirstTruth.seen, "no frame at all"
    first_at, centroid = FirstTruth.seen[0]
    assert first_at >= 0.5
    with ModuleHarness(DigiCam, {"source": "sim", "world_frame": "world"}) as cam:
        cam.push("camera_pose", Pose(matrix=T_WORLD_CAMERA, parent="world", child="camera"))
        cam.push("patch_pose", Pose(matrix=T_WORLD_PATCH, parent="world", child="patch"))
        expected = np.asarray(cam.step(0.1)["truth"][0].centroid, dtype=float)
    np.testing.assert_allclose(centroid, expected, atol=0.5)
    assert np.linalg.norm(expected - [320.0, 240.0]) > 50  # not where the stand-in put it
