"""A zoom camera's calibration: intrinsics and extrinsics tabulated at normalized zooms.

This is the content of the Sandia report's Appendix D file, independent of its XML or YAML form.

Units, as the report's own file uses them:

* intrinsics ``fx fy fxy u0 v0`` in pixels (``fxy`` is called ``skew`` here), distortion
  ``k1 k2 p1 p2`` unitless (OpenCV's model, on normalized coordinates);
* extrinsics ``dx dy dz`` in metres and ``thetax thetay thetaz`` (``rx ry rz`` here) in radians.
  The report states no units; its table only makes sense in these: the offsets of a few
  centimetres (dy = 0.041) are the optical centre's distance from the PTU mount in the custom
  housing, and dz grows by 15 mm as the zoom's nodal point moves forward. In millimetres or inches
  they would be fractions of a millimetre; the angles of a few hundredths are mounting
  misalignments of one to four degrees in radians, but below what a bench fixture can resolve
  in degrees.
* The extrinsics take mount-frame points into the camera frame (``X_cam = R X_mount + d``, as in
  Appendix B's ``[R | d]``), with ``R = Rz(rz) Ry(ry) Rx(rx)`` (rotations about the fixed x, y,
  then z axes; the report does not define the order, and for angles this small the orders agree to
  within ``theta^2 / 2``).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from umbra.modules.calib.camera_model import Intrinsics, PinholeCamera
from umbra.modules.calib.rotations import rotation_from_xyz
from umbra.modules.calib.zoom_interp import check_zooms, interpolate

FloatArray = NDArray[np.float64]

#: Intrinsic values in file order (the file's ``fxy`` is ``skew``).
INTRINSIC_KEYS = ("fx", "fy", "skew", "u0", "v0", "k1", "k2", "p1", "p2")
#: Extrinsic values in file order (the file's ``thetax thetay thetaz`` are ``rx ry rz``).
EXTRINSIC_KEYS = ("dx", "dy", "dz", "rx", "ry", "rz")


@dataclass(frozen=True, eq=False)
class ZoomSample:
    """Parameters at one zoom: ``intrinsics`` (9,) and ``extrinsics`` (6,) in file order/units."""

    zoom: float
    intrinsics: FloatArray
    extrinsics: FloatArray

    def camera(self) -> PinholeCamera:
        """The camera model: extrinsics ``R, d`` take mount-frame points into the camera frame."""
        i, e = self.intrinsics, self.extrinsics
        return PinholeCamera(Intrinsics.from_array(i[:5]), rotation_from_xyz(e[3:]), e[:3], i[5:9])

    def as_dict(self) -> dict:
        """``{"zoom", "intrinsics": {fx..p2}, "extrinsics": {dx..rz}}`` (file units)."""
        return {
            "zoom": float(self.zoom),
            "intrinsics": dict(zip(INTRINSIC_KEYS, map(float, self.intrinsics), strict=True)),
            "extrinsics": dict(zip(EXTRINSIC_KEYS, map(float, self.extrinsics), strict=True)),
        }


@dataclass(frozen=True, eq=False)
class ZoomTable:
    """One camera's table: ``zooms`` (n,), ``intrinsics`` (n, 9), ``extrinsics`` (n, 6)."""

    name: str
    zooms: FloatArray
    intrinsics: FloatArray
    extrinsics: FloatArray

    def __post_init__(self) -> None:
        zooms = check_zooms(self.zooms)
        intr = np.asarray(self.intrinsics, dtype=float).reshape(len(zooms), -1)
        extr = np.asarray(self.extrinsics, dtype=float).reshape(len(zooms), -1)
        if intr.shape[1] != 9 or extr.shape[1] != 6:
            raise ValueError(
                f"need 9 intrinsic and 6 extrinsic values per zoom, got {intr.shape[1]} and "
                f"{extr.shape[1]}"
            )
        if not (np.all(np.isfinite(intr)) and np.all(np.isfinite(extr))):
            raise ValueError("calibration values must be finite")
        if np.any(intr[:, :2] <= 0):
            raise ValueError("focal lengths fx, fy must be positive")
        object.__setattr__(self, "zooms", zooms)
        object.__setattr__(self, "intrinsics", intr)
        object.__setattr__(self, "extrinsics", extr)

    def __len__(self) -> int:
        return len(self.zooms)

    def sample(self, zoom: float) -> ZoomSample:
        """Parameters at ``zoom`` (0..1, within the table), linear between tabulated zooms."""
        intr, extr = interpolate(self.zooms, self.intrinsics, self.extrinsics, zoom)
        return ZoomSample(float(zoom), intr, extr)

    def row(self, index: int) -> ZoomSample:
        """The tabulated entry ``index``."""
        return ZoomSample(
            float(self.zooms[index]), self.intrinsics[index].copy(), self.extrinsics[index].copy()
        )


@dataclass(frozen=True, eq=False)
class ZoomFile:
    """A whole calibration file: its cameras, comment, and the path recorded inside it."""

    cameras: tuple[ZoomTable, ...]
    comment: str = ""
    recorded_path: str = ""

    def camera(self, name: str | None = None) -> ZoomTable:
        """The camera called ``name``, or the only camera when ``name`` is None."""
        if name is None:
            if len(self.cameras) != 1:
                names = ", ".join(repr(c.name) for c in self.cameras)
                raise KeyError(f"the file holds several cameras ({names}); name one")
            return self.cameras[0]
        for table in self.cameras:
            if table.name == name:
                return table
        names = ", ".join(repr(c.name) for c in self.cameras)
        raise KeyError(f"no camera {name!r} in the file (it has {names})")


def table_from_samples(name: str, samples: Iterable[ZoomSample]) -> ZoomTable:
    """Build a table from ``ZoomSample`` objects (sorted by zoom)."""
    ordered = sorted(samples, key=lambda s: s.zoom)
    return ZoomTable(
        name,
        np.array([s.zoom for s in ordered]),
        np.array([s.intrinsics for s in ordered]),
        np.array([s.extrinsics for s in ordered]),
    )
