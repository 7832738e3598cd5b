"""CamCalib and Targeting in a checked graph run by the scheduler (sim clock)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from umbra.connectors import Input, Module, Output, Parameters, param
from umbra.connectors.errors import UserError
from umbra.connectors.messages import CameraModel, Vector, ZoomState
from umbra.modules.calib.camcalib import REPORT_FILE, CamCalib
from umbra.modules.calib.camera_message import pinhole_from_message
from umbra.modules.calib.targeting import Targeting
from umbra.modules.calib.zoom_io import load_zoom_table
from umbra.runtime.graph.check import check_text
from umbra.runtime.registry import Registry
from umbra.runtime.scheduler import Scheduler, SchedulerOptions


class ZoomSweep(Module):
    """Sends a zoom that holds each value for three ticks: 0, 0, 0, 0.1, 0.1, 0.1, ..."""

    class Params(Parameters):
        step: float = param(0.1, "zoom increment every third tick")

    zoom = Output(ZoomState)

    def start(self) -> None:
        self.ticks = 0

    def step(self, now: float) -> None:
        zoom = min(1.0, self.params.step * (self.ticks // 3))
        self.zoom.send(ZoomState(zoom=zoom))
        self.ticks += 1


class ModelProbe(Module):
    """Keeps every camera model it receives."""

    model = Input(CameraModel, trigger=True)

    def start(self) -> None:
        self.seen: list[CameraModel] = []

    def step(self, now: float) -> None:
        if self.model.fresh:
            self.seen.append(self.model.get(now))


class TargetPixels(Module):
    """Projects a fixed 3-D target (base frame) through two camera models into pixels."""

    class Params(Parameters):
        target: list[float] = param([0.02, -0.03, 1.5], "target point in base (m)")

    camera_a = Input(CameraModel)
    camera_b = Input(CameraModel)
    pixel_a = Output(Vector)
    pixel_b = Output(Vector)

    def step(self, now: float) -> None:
        for model_in, out in ((self.camera_a, self.pixel_a), (self.camera_b, self.pixel_b)):
            model = model_in.get(now)
            if model is None:
                return
            T_base_mount = self.context.frames.lookup("base", model.mount)
            camera = pinhole_from_message(model, T_base_mount)
            out.send(Vector(values=camera.project(np.array(self.params.target))))


class PointProbe(Module):
    point = Input(Vector, trigger=True)

    def start(self) -> None:
        self.seen: list[np.ndarray] = []

    def step(self, now: float) -> None:
        if self.point.fresh:
            self.seen.append(np.asarray(self.point.get(now).values))


def registry() -> Registry:
    reg = Registry()
    for cls in (ZoomSweep, ModelProbe, TargetPixels, PointProbe, CamCalib, Targeting):
        reg.add(cls)
    return reg


GRAPH = """graph: calib
frames:
  base->ptu_left: {xyz: [-0.3, 0, 0], rpy_deg: [0, 8, 0]}
  base->ptu_right: {xyz: [0.3, 0, 0], rpy_deg: [0, -8, 0]}
modules:
  sweep: {type: ZoomSweep, rate: 10, params: {step: 0.05}}
  left: {type: CamCalib, params: {mount_frame: ptu_left, camera_name: left}}
  right: {type: CamCalib, params: {mount_frame: ptu_right, camera_name: right, zoom_tolerance: 0.0}}
  probe: {type: ModelProbe}
  pixels: {type: TargetPixels, rate: 10}
  target: {type: Targeting, params: {reference_frame: base, max_gap: 0.001}}
  points: {type: PointProbe}
connections:
  - sweep.zoom -> left.zoom
  - sweep.zoom -> right.zoom
  - left.camera -> probe.model
  - left.camera -> pixels.camera_a
  - right.camera -> pixels.camera_b
  - left.camera -> target.camera_a
  - right.camera -> target.camera_b
  - pixels.pixel_a -> target.pixel_a
  - pixels.pixel_b -> target.pixel_b
  - target.point -> points.point
"""


def test_graph_recomputes_on_zoom_change_and_targets(tmp_path: Path) -> None:
    plan = check_text(GRAPH, "calib.yaml", registry())
    scheduler = Scheduler(plan, SchedulerOptions(max_ticks=30, output_dir=tmp_path))
    result = scheduler.run()
    assert result.exit_code == 0
    seen = scheduler.modules["probe"].seen
    # 30 ticks, the zoom changes every third tick: ten models, one per zoom.
    np.testing.assert_allclose([m.zoom for m in seen], np.arange(10) * 0.05)
    table = load_zoom_table(REPORT_FILE)
    for model in seen:
        assert model.fx == pytest.approx(table.sample(model.zoom).intrinsics[0])
        assert model.mount == "ptu_left" and model.frame == "left"
    assert scheduler.modules["left"].summary()["models_computed"] == 10
    points = scheduler.modules["points"].seen
    assert len(points) >= 20
    np.testing.assert_allclose(np.array(points), [[0.02, -0.03, 1.5]] * len(points), atol=1e-9)


def test_graph_with_bad_parameter_is_refused() -> None:
    bad = GRAPH.replace("zoom_tolerance: 0.0", "zoom_tolerance: 0.5")
    with pytest.raises(UserError) as caught:
        check_text(bad, "calib.yaml", registry())
    assert "calib.yaml:" in str(caught.value) and "zoom_tolerance" in str(caught.value)
