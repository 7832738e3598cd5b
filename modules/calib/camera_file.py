"""A small YAML file of named, posed cameras, for ``umbra calib pose`` and ``triangulate``.

::

    cameras:
      left:                                  # intrinsics given here
        intrinsics: {fx: 900, fy: 900, skew: 0, u0: 320, v0: 240}   # px; + k1 k2 p1 p2 [k3]
        pose: {xyz: [0.0, 0.1, 0.0], rpy_deg: [0, 5, 0]}            # camera in the reference
      right:                                 # or from a zoom calibration file at a zoom
        zoom_file: zoom_cam.xml              # relative to this file
        zoom: 0.2
        camera: zcam                         # optional: name in the zoom file
        mount_pose: {xyz: [0.4, 0.1, 0.0], rpy_deg: [0, -5, 0]}   # the file's mount frame

Poses are the camera's (or mount's) pose in the common reference frame: translation ``xyz``
in metres and fixed-axis roll, pitch, yaw in degrees (``R = Rz(yaw) Ry(pitch) Rx(roll)``, the
convention of graph frames). Errors are ``UserError("FILE:LINE: error: ...")``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

from umbra.connectors.errors import UserError
from umbra.modules.calib import yaml_nodes as yn
from umbra.modules.calib.camera_model import Intrinsics, PinholeCamera
from umbra.modules.calib.rotations import invert_transform
from umbra.modules.calib.yaml_nodes import SpotError
from umbra.modules.calib.zoom_io import load_zoom_table
from umbra.modules.geometry.transforms import transform_from_xyz_rpy_deg

INTRINSIC_REQUIRED = ("fx", "fy", "u0", "v0")
INTRINSIC_OPTIONAL = ("skew", "k1", "k2", "p1", "p2", "k3")


def _pose(node: yaml.Node, what: str) -> np.ndarray:
    fields = yn.mapping(node, what, ("xyz",), ("rpy_deg",))
    xyz = yn.numbers(fields["xyz"], f"{what}.xyz", 3)
    rpy = yn.numbers(fields["rpy_deg"], f"{what}.rpy_deg", 3) if "rpy_deg" in fields else [0] * 3
    return transform_from_xyz_rpy_deg(xyz, rpy)


def _inline(fields: dict[str, yaml.Node]) -> PinholeCamera:
    values = yn.mapping(fields["intrinsics"], "intrinsics", INTRINSIC_REQUIRED, INTRINSIC_OPTIONAL)
    get = {k: yn.number(v, f"intrinsics.{k}") for k, v in values.items()}
    if get["fx"] <= 0 or get["fy"] <= 0:
        raise SpotError.at(fields["intrinsics"], "focal lengths fx, fy must be positive")
    intrinsics = Intrinsics(get["fx"], get["fy"], get.get("skew", 0.0), get["u0"], get["v0"])
    distortion = np.array([get.get(k, 0.0) for k in ("k1", "k2", "p1", "p2", "k3")])
    if "pose" not in fields:
        raise SpotError.at(fields["intrinsics"], "a camera with intrinsics needs a 'pose'")
    camera = PinholeCamera(intrinsics, distortion=distortion)
    return camera.with_extrinsic_matrix(invert_transform(_pose(fields["pose"], "pose")))


def _from_zoom_file(fields: dict[str, yaml.Node], base: Path) -> PinholeCamera:
    if "mount_pose" not in fields or "zoom" not in fields:
        raise SpotError.at(
            fields["zoom_file"], "a camera from a zoom_file needs 'zoom' and 'mount_pose'"
        )
    path = base / yn.text(fields["zoom_file"], "zoom_file")
    name = yn.text(fields["camera"], "camera") if "camera" in fields else None
    if "method" in fields and yn.text(fields["method"], "method") != "linear":
        raise SpotError.at(
            fields["method"],
            "zoom interpolation is linear between tabulated zooms (the report's rule); "
            f"expected no 'method' or 'linear', found {yn.text(fields['method'], 'method')!r}",
        )
    zoom = yn.number(fields["zoom"], "zoom")
    table = load_zoom_table(path, name)
    try:
        in_mount = table.sample(zoom).camera()
    except ValueError as error:
        raise SpotError.at(fields["zoom"], str(error)) from None
    T_mount_ref = invert_transform(_pose(fields["mount_pose"], "mount_pose"))
    return in_mount.with_extrinsic_matrix(in_mount.extrinsic_matrix() @ T_mount_ref)


def parse_cameras(
    content: str, source: str = "<string>", base: Path | None = None
) -> dict[str, PinholeCamera]:
    """Cameras by name, extrinsics relative to the common reference frame."""
    root = yn.compose(content, source)
    if root is None:
        raise UserError(f"{source}:1: error: the file is empty; expected a 'cameras' mapping")
    cameras: dict[str, PinholeCamera] = {}
    try:
        top = yn.mapping(root, "the file", ("cameras",))
        for name, _, node in yn.named_mapping(top["cameras"], "cameras"):
            fields = yn.mapping(
                node,
                f"camera {name!r}",
                (),
                ("intrinsics", "pose", "zoom_file", "zoom", "camera", "method", "mount_pose"),
            )
            if ("intrinsics" in fields) == ("zoom_file" in fields):
                raise SpotError.at(
                    node, f"camera {name!r} needs exactly one of 'intrinsics' or 'zoom_file'"
                )
            if "intrinsics" in fields:
                cameras[name] = _inline(fields)
            else:
                cameras[name] = _from_zoom_file(fields, base or Path("."))
    except SpotError as failure:
        raise UserError(f"{source}:{failure.line}: error: {failure.message}") from None
    return cameras


def load_cameras(path: str | Path) -> dict[str, PinholeCamera]:
    """Read a cameras file (zoom files in it are relative to its directory)."""
    path = Path(path)
    return parse_cameras(yn.read_text(path, "cameras file"), str(path), path.parent)
