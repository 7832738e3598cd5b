"""``umbra pose-tool SESSION.yaml``: solve a camera mount from clicked calibration points.

The session file (see :mod:`umbra.modules.calib.pose_tool_file`; the 3-D view's pose tool writes the
same file) names the unknown mount ``parent->child``, the camera intrinsics, the calibration
points (world, metres) and, per snapshot, the known chain on both sides of the mount and the
clicked pixels. Prints the solved mount, the reprojection residual of every click (before, at
the believed mount, and after) and, with ``--output``, writes the mount as a calibration file
(a graph ``frames:`` entry) or, with ``--graph``, updates that frame of a graph file in place.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from umbra.connectors.cli_support import print_json
from umbra.connectors.errors import UserError
from umbra.modules.calib import yaml_nodes as yn
from umbra.modules.calib.errors import CalibrationError
from umbra.modules.calib.pose_tool import pose_error, solve_mount
from umbra.modules.calib.pose_tool_file import frames_text, load_session, update_graph_frame
from umbra.modules.geometry.transforms import xyz_rpy_deg_from_transform

NAME = "pose-tool"
HELP = "camera-pose tool: solve a camera mount from clicked points over snapshots (nPnP)"
GUIDE = "docs/guide/calibration.md"  # the guide page this command's --help points to


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("session", metavar="SESSION", help="pose-tool session file (.yaml)")
    parser.add_argument(
        "-o", "--output", metavar="FILE", help="write the solved mount as a frames calibration file"
    )
    parser.add_argument(
        "--graph", metavar="GRAPH", help="update the mount's frame in this graph file in place"
    )
    parser.add_argument(
        "--max-rms-px",
        type=float,
        default=5.0,
        help="refuse to save a mount whose reprojection RMS is above this (default 5 px)",
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def main(args: argparse.Namespace) -> int:
    if not (math.isfinite(args.max_rms_px) and args.max_rms_px > 0):
        raise UserError(
            f"--max-rms-px: expected a finite number of pixels > 0, found {args.max_rms_px}"
        )
    session = load_session(args.session)
    try:
        result = solve_mount(session.snapshots, session.initial)
    except CalibrationError as error:
        raise UserError(f"{args.session}: error: cannot solve the mount: {error}") from None
    xyz, rpy = xyz_rpy_deg_from_transform(result.T_parent_child)
    clicks = []
    for index, residuals in enumerate(result.residuals):
        before = result.initial_residuals[index] if result.initial_residuals else None
        for k, name in enumerate(session.click_names[index]):
            before_px = None if before is None else float(np.linalg.norm(before[k]))
            clicks.append(
                {
                    "snapshot": index + 1,
                    "point": name,
                    "line": session.click_lines[index][k],
                    "residual_px": float(np.linalg.norm(residuals[k])),
                    "residual_uv": residuals[k].tolist(),
                    # None also where the believed mount puts the point at the camera's centre
                    "before_px": before_px
                    if before_px is None or math.isfinite(before_px)
                    else None,
                }
            )
    change = None
    if session.initial is not None:
        angle, offset = pose_error(result.T_parent_child, session.initial)
        change = {"angle_deg": float(np.degrees(angle)), "offset_m": offset}
    mount = f"{session.parent}->{session.child}"
    saved = _save(args, session, result.T_parent_child, result.rms_px)
    if args.json:
        print_json(
            {
                "mount": mount,
                "T": result.T_parent_child.tolist(),
                "xyz": xyz.tolist(),
                "rpy_deg": rpy.tolist(),
                "rms_px": result.rms_px,
                "max_px": result.max_px,
                "iterations": result.iterations,
                "change_from_initial": change,
                "warnings": list(result.warnings),
                "standard_errors": result.standard_errors,
                "interval_95": result.interval_95(),
                "covariance": None if result.covariance is None else result.covariance.tolist(),
                "clicks": clicks,
                "saved": saved,
            }
        )
        return 0
    total = sum(len(n) for n in session.click_names)
    print(
        f"mount {mount} from {total} clicks over {len(session.snapshots)} snapshots "
        f"({result.iterations} Gauss-Newton iterations)"
    )
    print(f"  xyz      [{xyz[0]:.5f}, {xyz[1]:.5f}, {xyz[2]:.5f}] m")
    print(f"  rpy_deg  [{rpy[0]:.4f}, {rpy[1]:.4f}, {rpy[2]:.4f}] (fixed axes x, y, z)")
    if change is not None:
        print(
            f"  moved from the believed mount by {change['angle_deg']:.3f} deg and "
            f"{1000 * change['offset_m']:.1f} mm"
        )
    print(f"  reprojection RMS {result.rms_px:.3f} px, worst {result.max_px:.3f} px")
    if result.covariance is not None:
        half = result.interval_95()
        print(
            "  95 % intervals (click noise from the residuals): rotation about x y z +-"
            f"[{', '.join(f'{np.degrees(half[k]):.3f}' for k in ('rx', 'ry', 'rz'))}] deg, "
            f"xyz +-[{', '.join(f'{1000 * half[k]:.1f}' for k in ('x', 'y', 'z'))}] mm"
        )
    for warning in result.warnings:
        print(f"  warning: {warning}")
    print("  snapshot  point            line  residual px  (before px)")
    for c in clicks:
        before_text = "" if c["before_px"] is None else f"({c['before_px']:.2f})"
        print(
            f"  {c['snapshot']:8d}  {c['point']:<15s} {c['line']:5d}  "
            f"{c['residual_px']:11.3f}  {before_text}"
        )
    for path in saved:
        print(f"wrote {path}")
    return 0


def _save(args: argparse.Namespace, session, T_parent_child: np.ndarray, rms_px: float) -> list:
    if not (args.output or args.graph):
        return []
    if rms_px > args.max_rms_px:
        raise UserError(
            f"{args.session}: error: reprojection RMS {rms_px:.2f} px is above --max-rms-px "
            f"{args.max_rms_px:g}; check the clicks (nothing written)"
        )
    saved = []
    comment = f"camera mount solved by umbra pose-tool from {args.session} (RMS {rms_px:.3f} px)"
    if args.output:
        out = Path(args.output)
        try:
            out.write_text(frames_text(session.parent, session.child, T_parent_child, comment))
        except OSError as error:
            raise UserError(f"{out}: error: cannot write: {error.strerror}") from None
        saved.append(str(out))
    if args.graph:
        graph = Path(args.graph)
        text = yn.read_text(graph, "graph file")
        updated = update_graph_frame(
            text, session.parent, session.child, T_parent_child, str(graph)
        )
        try:
            graph.write_text(updated)
        except OSError as error:
            raise UserError(f"{graph}: error: cannot write: {error.strerror}") from None
        saved.append(str(graph))
    return saved
