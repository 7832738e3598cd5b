"""The camera-pose tool's session file: clicked points over snapshots, for ``umbra pose-tool``.

The 3-D view writes the same file when the operator saves a pose-tool session::

    mount: ptu_head->camera            # the unknown transform, graph frame syntax parent->child
    initial: {xyz: [0.03, 0, 0.05], rpy_deg: [-90, 0, -90]}   # believed mount (optional)
    camera: {fx: 820, fy: 815, u0: 331, v0: 244}  # px; optional skew, k1 k2 p1 p2 k3
    points:                            # calibration points picked in the model (world, metres)
      tray_a: [0.52, -0.30, 0.53]
      tray_b: [0.70, -0.30, 0.55]
    snapshots:
      - parent: {xyz: [0.6, -0.9, 0.78], rpy_deg: [0, 14.3, 89.6]}  # T_world_parent (default: I)
        camera_in_child: {xyz: [0, 0, 0]}          # T_child_camera (optional, default: I)
        clicks: {tray_a: [219.0, 436.5], tray_b: [460.2, 411.0]}   # pixels (u, v)

Translations in metres, fixed-axis roll, pitch, yaw in degrees (``R = Rz(yaw) Ry(pitch)
Rx(roll)``, the graph frames' convention). Errors are ``UserError("FILE:LINE: error: ...")``.

The file is checked before anything is solved or written: the mount's frame names are graph frame
names (what ``--graph`` writes passes ``umbra check``), and the clicked points, seen from the
mount's parent frame, must pin the mount down: clicks that are all on one point, or on one line,
leave it free to turn (a solver would report such a "mount" at 0 px) and are refused with the
reason.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from umbra.connectors.errors import UserError
from umbra.connectors.frames import frame_name_problem
from umbra.modules.calib import yaml_nodes as yn
from umbra.modules.calib.camera_model import Intrinsics, PinholeCamera
from umbra.modules.calib.pose_tool import MountSnapshot
from umbra.modules.calib.yaml_nodes import SpotError
from umbra.modules.geometry.transforms import transform_from_xyz_rpy_deg, xyz_rpy_deg_from_transform

CAMERA_REQUIRED = ("fx", "fy", "u0", "v0")
CAMERA_OPTIONAL = ("skew", "k1", "k2", "p1", "p2", "k3")


@dataclass(frozen=True, eq=False)
class PoseToolSession:
    """A parsed session: the mount's frame names, the believed mount (or None), snapshots, and
    for every snapshot the names and source lines of its clicks."""

    parent: str
    child: str
    initial: np.ndarray | None
    snapshots: list[MountSnapshot]
    click_names: list[list[str]]
    click_lines: list[list[int]]


def _pose(node: yaml.Node, what: str) -> np.ndarray:
    fields = yn.mapping(node, what, ("xyz",), ("rpy_deg",))
    xyz = yn.numbers(fields["xyz"], f"{what}.xyz", 3)
    rpy = yn.numbers(fields["rpy_deg"], f"{what}.rpy_deg", 3) if "rpy_deg" in fields else [0] * 3
    return transform_from_xyz_rpy_deg(xyz, rpy)


def _camera(node: yaml.Node) -> PinholeCamera:
    values = yn.mapping(node, "camera", CAMERA_REQUIRED, CAMERA_OPTIONAL)
    get = {k: yn.number(v, f"camera.{k}") for k, v in values.items()}
    if get["fx"] <= 0 or get["fy"] <= 0:
        raise SpotError.at(node, f"focal lengths must be positive, found {get['fx']}, {get['fy']}")
    intrinsics = Intrinsics(get["fx"], get["fy"], get.get("skew", 0.0), get["u0"], get["v0"])
    distortion = np.array([get.get(k, 0.0) for k in ("k1", "k2", "p1", "p2", "k3")])
    return PinholeCamera(intrinsics, distortion=distortion)


def _mount_names(node: yaml.Node) -> tuple[str, str]:
    value = yn.text(node, "mount")
    parent, sep, child = value.partition("->")
    if not sep or not parent.strip() or not child.strip():
        raise SpotError.at(node, f"mount must be written parent->child, found {value!r}")
    for name in (parent.strip(), child.strip()):
        problem = frame_name_problem(name)
        if problem:
            raise SpotError.at(node, f"mount {value!r}: {problem}")
    if parent.strip() == child.strip():
        raise SpotError.at(node, f"mount {value!r} names one frame twice; expected parent->child")
    return parent.strip(), child.strip()


#: Clicked points closer than this to their centroid are one point [m].
ONE_POINT_M = 1e-4
#: Points whose spread across their main line is less than this fraction of the spread along it
#: are on one line.
ONE_LINE_RATIO = 1e-3


def _geometry_problem(snapshots: list[MountSnapshot], total: int) -> str:
    """Why the clicked points cannot determine the mount; empty when they can. The points are
    taken in the mount's parent frame (a point clicked from two parent poses counts twice)."""
    in_parent = [
        (np.linalg.inv(s.T_world_parent) @ np.c_[s.points_world, np.ones(len(s.points_world))].T)[
            :3
        ].T
        for s in snapshots
        if len(s.points_world)
    ]
    points = np.vstack(in_parent)
    spread = np.linalg.svd(points - points.mean(axis=0), compute_uv=False)
    rms = spread / np.sqrt(len(points))
    if rms[0] < ONE_POINT_M:
        return (
            f"all {total} clicks are on one point (seen from the mount's parent frame): the mount "
            "is not determined; click at least 3 points that are not on one line"
        )
    if len(rms) < 2 or rms[1] < ONE_LINE_RATIO * rms[0]:
        return (
            f"the {total} clicked points lie on one line (seen from the mount's parent frame): "
            "the mount could turn about it; click a point off that line"
        )
    return ""


def parse_session(content: str, source: str = "<string>") -> PoseToolSession:
    """Parse a pose-tool session file's text."""
    root = yn.compose(content, source)
    if root is None:
        raise UserError(
            f"{source}:1: error: the file is empty; expected mount, camera, points, snapshots"
        )
    try:
        top = yn.mapping(root, "the file", ("mount", "camera", "points", "snapshots"), ("initial",))
        parent, child = _mount_names(top["mount"])
        initial = _pose(top["initial"], "initial") if "initial" in top else None
        camera = _camera(top["camera"])
        points = {
            name: np.array(yn.numbers(value, f"point {name!r}", 3))
            for name, _, value in yn.named_mapping(top["points"], "points")
        }
        snapshots, names_all, lines_all = [], [], []
        for index, item in enumerate(yn.sequence(top["snapshots"], "snapshots")):
            what = f"snapshot {index + 1}"
            fields = yn.mapping(item, what, ("clicks",), ("parent", "camera_in_child"))
            T_world_parent = (
                _pose(fields["parent"], f"{what}.parent") if "parent" in fields else np.eye(4)
            )
            T_child_camera = (
                _pose(fields["camera_in_child"], f"{what}.camera_in_child")
                if "camera_in_child" in fields
                else np.eye(4)
            )
            names, lines, world, pixels = [], [], [], []
            for name, key, value in yn.named_mapping(fields["clicks"], f"{what}.clicks"):
                if name not in points:
                    known = ", ".join(sorted(points))
                    raise SpotError.at(key, f"click on unknown point {name!r}; points are {known}")
                world.append(points[name])
                pixels.append(yn.numbers(value, f"click {name!r} (u, v pixels)", 2))
                names.append(name)
                lines.append(key.start_mark.line + 1)
            snapshots.append(
                MountSnapshot(
                    camera, np.array(world), np.array(pixels), T_world_parent, T_child_camera
                )
            )
            names_all.append(names)
            lines_all.append(lines)
        total = sum(len(n) for n in names_all)
        if total < 3:
            raise SpotError.at(
                top["snapshots"], f"the mount needs at least 3 clicks in all, found {total}"
            )
        problem = _geometry_problem(snapshots, total)
        if problem:
            raise SpotError.at(top["snapshots"], problem)
    except SpotError as failure:
        raise UserError(f"{source}:{failure.line}: error: {failure.message}") from None
    return PoseToolSession(parent, child, initial, snapshots, names_all, lines_all)


def load_session(path: str | Path) -> PoseToolSession:
    """Read a pose-tool session file."""
    return parse_session(yn.read_text(path, "pose-tool session file"), str(path))


def _check_names(parent: str, child: str) -> None:
    """ValueError when ``parent->child`` is no frame entry a graph accepts."""
    for name in (parent, child):
        problem = frame_name_problem(name)
        if problem:
            raise ValueError(problem)


def _flow_pose(T: np.ndarray) -> str:
    xyz, rpy = xyz_rpy_deg_from_transform(T)
    return (
        "{xyz: ["
        + ", ".join(f"{v:.6f}" for v in xyz)
        + "], rpy_deg: ["
        + ", ".join(f"{v:.5f}" for v in rpy)
        + "]}"
    )


def session_text(
    parent: str,
    child: str,
    camera: PinholeCamera,
    points: dict[str, np.ndarray],
    snapshots: list[tuple[np.ndarray, np.ndarray, dict[str, tuple[float, float]]]],
    initial: np.ndarray | None = None,
) -> str:
    """A session file's text; ``snapshots`` are ``(T_world_parent, T_child_camera, clicks)``.
    ValueError for a mount name a graph would refuse (nothing is written with it)."""
    _check_names(parent, child)
    f = camera.intrinsics
    k1, k2, p1, p2, k3 = (float(v) for v in camera.distortion)
    lines = [
        "# camera-pose tool session (umbra pose-tool FILE solves it)",
        f"mount: {parent}->{child}",
    ]
    if initial is not None:
        lines.append(f"initial: {_flow_pose(initial)}")
    lines.append(
        f"camera: {{fx: {f.fx:.6g}, fy: {f.fy:.6g}, skew: {f.skew:.6g}, u0: {f.u0:.6g}, "
        f"v0: {f.v0:.6g}, k1: {k1:.6g}, k2: {k2:.6g}, p1: {p1:.6g}, p2: {p2:.6g}, k3: {k3:.6g}}}"
    )
    lines.append("points:")
    for name, p in points.items():
        lines.append(f"  {name}: [{p[0]:.6f}, {p[1]:.6f}, {p[2]:.6f}]")
    lines.append("snapshots:")
    for T_world_parent, T_child_camera, clicks in snapshots:
        lines.append(f"  - parent: {_flow_pose(T_world_parent)}")
        lines.append(f"    camera_in_child: {_flow_pose(T_child_camera)}")
        body = ", ".join(f"{n}: [{u:.3f}, {v:.3f}]" for n, (u, v) in clicks.items())
        lines.append(f"    clicks: {{{body}}}")
    return "\n".join(lines) + "\n"


def frames_text(parent: str, child: str, T_parent_child: np.ndarray, comment: str) -> str:
    """A calibration file with the mount as a graph ``frames:`` entry (ValueError for a mount
    name a graph would refuse)."""
    _check_names(parent, child)
    return f"# {comment}\nframes:\n  {parent}->{child}: {_flow_pose(T_parent_child)}\n"


def update_graph_frame(
    graph_text: str, parent: str, child: str, T_parent_child: np.ndarray, source: str
) -> str:
    """The graph file's text with the ``parent->child`` frame replaced (or added under
    ``frames:``), everything else (comments, order) untouched; ValueError for a mount name a
    graph would refuse."""
    _check_names(parent, child)
    entry = _flow_pose(T_parent_child)
    key = f"{parent}->{child}:"
    lines = graph_text.splitlines(keepends=True)
    frames_at = None
    for index, line in enumerate(lines):
        stripped = line.lstrip()
        if line.startswith("frames:"):
            frames_at = index
        if frames_at is not None and index > frames_at and stripped.startswith(key):
            indent = line[: len(line) - len(stripped)]
            rest = stripped[len(key) :].rstrip("\n")
            close = rest.find("}")
            if not rest.strip().startswith("{") or close < 0:
                raise UserError(
                    f"{source}:{index + 1}: error: frame {parent}->{child} must be a one-line "
                    "{xyz: [...], rpy_deg: [...]} mapping to be updated in place"
                )
            comment = rest[close + 1 :]
            lines[index] = f"{indent}{key} {entry}{comment}\n"
            return "".join(lines)
    if frames_at is None:
        raise UserError(
            f"{source}: error: no top-level 'frames:' section to add {parent}->{child} to"
        )
    lines.insert(frames_at + 1, f"  {key} {entry}   # solved by umbra pose-tool\n")
    return "".join(lines)
