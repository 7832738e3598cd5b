"""The YAML form of a zoom calibration file (same content as the Appendix D XML).

::

    units: {length: m, angle: rad}      # optional; also mm / deg, converted on reading
    comment: Sony Zoom Camera Values ...  # optional
    recorded_path: C:/ieddApps/camera/zoom_cam.xml   # optional
    cameras:
      - name: zcam
        zooms:
          - zoom: 0.0
            intrinsics: {fx: 740.09, fy: 741.6, skew: -4.58, u0: 344.25, v0: 212.84,
                         k1: 0.0, k2: 0.0, p1: 0.0, p2: 0.0}
            extrinsics: {dx: -0.004, dy: 0.041, dz: 0.006, rx: 0.009, ry: -0.004, rz: 0.034}

Written files always use metres and radians. Errors are ``UserError("FILE:LINE: error: ...")``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import yaml

from umbra.connectors.errors import UserError
from umbra.modules.calib import yaml_nodes as yn
from umbra.modules.calib.yaml_nodes import SpotError
from umbra.modules.calib.zoom_table import EXTRINSIC_KEYS, INTRINSIC_KEYS, ZoomFile, ZoomTable

LENGTH_UNITS = {"m": 1.0, "mm": 1e-3}
ANGLE_UNITS = {"rad": 1.0, "deg": math.pi / 180.0}


def _units(node: yaml.Node | None) -> tuple[float, float]:
    if node is None:
        return 1.0, 1.0
    fields = yn.mapping(node, "units", (), ("length", "angle"))
    scales = []
    for key, table, default in (("length", LENGTH_UNITS, "m"), ("angle", ANGLE_UNITS, "rad")):
        unit = yn.text(fields[key], f"units.{key}") if key in fields else default
        if unit not in table:
            raise SpotError.at(
                fields[key], f"units.{key} must be one of {', '.join(table)}, got {unit!r}"
            )
        scales.append(table[unit])
    return scales[0], scales[1]


def _camera(node: yaml.Node, length: float, angle: float) -> ZoomTable:
    fields = yn.mapping(node, "a camera", ("name", "zooms"))
    name = yn.text(fields["name"], "camera name")
    zooms: list[float] = []
    intrinsics: list[list[float]] = []
    extrinsics: list[list[float]] = []
    previous_line = 0
    for entry in yn.sequence(fields["zooms"], f"zooms of camera {name!r}"):
        parts = yn.mapping(entry, "a zoom entry", ("zoom", "intrinsics", "extrinsics"))
        zoom = yn.number(parts["zoom"], "zoom")
        if not 0.0 <= zoom <= 1.0:
            raise SpotError.at(parts["zoom"], f"zoom {zoom:g} is outside the normalized range 0..1")
        if zooms and zoom <= zooms[-1]:
            raise SpotError.at(
                parts["zoom"],
                f"zoom {zoom:g} does not increase from the previous zoom {zooms[-1]:g} "
                f"(line {previous_line}); list zooms in increasing order",
            )
        previous_line = parts["zoom"].start_mark.line + 1
        intr_fields = yn.mapping(parts["intrinsics"], "intrinsics", INTRINSIC_KEYS)
        intr = [yn.number(intr_fields[k], f"intrinsics.{k}") for k in INTRINSIC_KEYS]
        if intr[0] <= 0 or intr[1] <= 0:
            raise SpotError.at(parts["intrinsics"], "focal lengths fx, fy must be positive")
        extr_fields = yn.mapping(parts["extrinsics"], "extrinsics", EXTRINSIC_KEYS)
        extr = [yn.number(extr_fields[k], f"extrinsics.{k}") for k in EXTRINSIC_KEYS]
        extr = [v * length for v in extr[:3]] + [v * angle for v in extr[3:]]
        zooms.append(zoom)
        intrinsics.append(intr)
        extrinsics.append(extr)
    return ZoomTable(name, np.array(zooms), np.array(intrinsics), np.array(extrinsics))


def parse_zoom_yaml(content: str, source: str = "<string>") -> ZoomFile:
    """Parse the YAML form; errors are ``UserError("SOURCE:LINE: error: ...")``."""
    root = yn.compose(content, source)
    if root is None:
        raise UserError(f"{source}:1: error: the file is empty; expected a 'cameras' list")
    try:
        fields = yn.mapping(root, "the file", ("cameras",), ("units", "comment", "recorded_path"))
        length, angle = _units(fields.get("units"))
        cameras = []
        seen: set[str] = set()
        for node in yn.sequence(fields["cameras"], "cameras"):
            table = _camera(node, length, angle)
            if table.name in seen:
                raise SpotError.at(node, f"second camera named {table.name!r}")
            seen.add(table.name)
            cameras.append(table)
        comment = yn.text(fields["comment"], "comment") if "comment" in fields else ""
        recorded = (
            yn.text(fields["recorded_path"], "recorded_path") if "recorded_path" in fields else ""
        )
    except SpotError as failure:
        raise UserError(f"{source}:{failure.line}: error: {failure.message}") from None
    return ZoomFile(tuple(cameras), comment.strip(), recorded.strip())


def read_zoom_yaml(path: str | Path) -> ZoomFile:
    """Read the YAML form of a zoom calibration file."""
    return parse_zoom_yaml(yn.read_text(path, "zoom calibration file"), str(path))


def _flow(values: dict[str, float]) -> str:
    return "{" + ", ".join(f"{k}: {float(v)!r}" for k, v in values.items()) + "}"


def format_zoom_yaml(zoom_file: ZoomFile) -> str:
    """YAML text in metres and radians, one zoom entry per three lines, numbers exact."""
    lines = [
        "# Zoom camera calibration: the YAML form of the Sandia report's Appendix D XML.",
        "# intrinsics in pixels; extrinsics take mount points into the camera frame.",
        "units: {length: m, angle: rad}",
    ]
    if zoom_file.comment:
        lines.append(f"comment: {json.dumps(zoom_file.comment)}")
    if zoom_file.recorded_path:
        lines.append(f"recorded_path: {json.dumps(zoom_file.recorded_path)}")
    lines.append("cameras:")
    for table in zoom_file.cameras:
        lines += [f"  - name: {json.dumps(table.name)}", "    zooms:"]
        for i in range(len(table)):
            row = table.row(i).as_dict()
            lines += [
                f"      - zoom: {row['zoom']!r}",
                f"        intrinsics: {_flow(row['intrinsics'])}",
                f"        extrinsics: {_flow(row['extrinsics'])}",
            ]
    return "\n".join(lines) + "\n"


def write_zoom_yaml(path: str | Path, zoom_file: ZoomFile) -> None:
    """Write the YAML form."""
    Path(path).write_text(format_zoom_yaml(zoom_file), encoding="utf-8")
