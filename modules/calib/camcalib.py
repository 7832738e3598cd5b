"""CamCalib: the camera model at the current zoom, from a zoom calibration file.

As in section 5.6 of the Sandia report: the SONY module reports the normalized zoom; CamCalib
interpolates the bench calibration (Appendix D file) at that zoom and publishes the camera model
for the targeting code, as if a fixed camera had taken the snapshot.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from pydantic import PrivateAttr, model_validator

from umbra.connectors import Input, Module, Output, Parameters, ParamProblem, UserError, param
from umbra.connectors.limits import MAX_IMAGE_SIDE_PX
from umbra.connectors.messages import CameraModel, ZoomState
from umbra.modules.calib.camera_message import camera_message
from umbra.modules.calib.zoom_io import load_zoom_file
from umbra.modules.calib.zoom_table import ZoomTable

#: The report's own calibration file, shipped with the project.
REPORT_FILE = Path(__file__).resolve().parent / "data" / "zoom_cam.xml"


class CamCalib(Module["CamCalib.Params"]):
    """Camera model (intrinsics, distortion, extrinsics in its mount) at the current zoom.

    Reads the zoom calibration file at start (Appendix D XML, or its YAML form); on each new zoom
    sample whose zoom differs from the last one used by more than ``zoom_tolerance`` it
    interpolates the table linearly (the report's rule, :mod:`umbra.modules.calib.zoom_interp`) and
    publishes a ``CameraModel``. Zooms outside the tabulated range are clamped to it (and
    counted); samples without a known zoom (NaN) are ignored.
    """

    TYPE = "CamCalib"

    class Params(Parameters):
        calibration_file: str = param(
            "", "zoom calibration file (.xml as Appendix D, or .yaml); empty: the report's file"
        )
        camera: str = param("", "camera name in the file (<SR_cam>); empty: its only camera")
        zoom_tolerance: float = param(
            1e-6, "smallest zoom change that recomputes the model", unit="1", ge=0, le=0.1
        )
        width: int = param(640, "image width", unit="px", gt=0, le=MAX_IMAGE_SIDE_PX)
        height: int = param(480, "image height", unit="px", gt=0, le=MAX_IMAGE_SIDE_PX)
        mount_frame: str = param("tool", "frame the file's extrinsics are relative to")
        camera_name: str = param(
            "camera", "frame name carried in the model (zoom-dependent, so not a static frame)"
        )

        _table: ZoomTable = PrivateAttr()

        @model_validator(mode="after")
        def _load_table(self) -> CamCalib.Params:
            """The file is read and its camera found when the parameters are validated, so a
            missing file or camera is a parameter error ``umbra check`` reports."""
            path = Path(self.calibration_file) if self.calibration_file else REPORT_FILE
            try:
                zoom_file = load_zoom_file(path)
            except UserError as exc:
                raise ParamProblem("calibration_file", f"cannot be used: {exc}") from None
            try:
                self._table = zoom_file.camera(self.camera or None)
            except KeyError as exc:
                raise ParamProblem("camera", f"is not in {path}: {exc.args[0]}") from None
            return self

        @property
        def table(self) -> ZoomTable:
            """The calibration table of the camera."""
            return self._table

    zoom = Input(ZoomState, trigger=True, doc="normalized zoom 0 (wide) .. 1 (tele)")
    camera = Output(CameraModel, doc="camera model at the zoom (published when it changes)")

    def start(self) -> None:
        self.table: ZoomTable = self.params.table
        self._range = (float(self.table.zooms[0]), float(self.table.zooms[-1]))
        self._last_zoom: float | None = None
        self._computed = 0
        self._clamped = 0
        self._ignored = 0

    def step(self, now: float) -> None:
        if not self.zoom.fresh:
            return
        sample = self.zoom.get(now)
        if sample is None:
            return
        if not math.isfinite(sample.zoom):
            self._ignored += 1
            return
        zoom = self._clamp(sample.zoom)
        if self._last_zoom is not None and abs(zoom - self._last_zoom) <= (
            self.params.zoom_tolerance
        ):
            return
        self._last_zoom = zoom
        self._computed += 1
        model = self.table.sample(zoom).camera()
        self.camera.send(
            camera_message(
                model,
                zoom=zoom,
                width=self.params.width,
                height=self.params.height,
                mount=self.params.mount_frame,
                frame=self.params.camera_name,
                stamp=sample.stamp,
            )
        )

    def _clamp(self, zoom: float) -> float:
        low, high = self._range
        if low <= zoom <= high:
            return zoom
        self._clamped += 1
        if self._clamped == 1:
            self.log.warning(
                "zoom %.4f outside the calibrated range %g..%g: clamped", zoom, low, high
            )
        return min(max(zoom, low), high)

    def summary(self) -> dict[str, Any]:
        return {
            "models_computed": self._computed,
            "zoom_clamped": self._clamped,
            "zoom_unknown": self._ignored,
        }
