"""``umbra arm``: forward kinematics and the geometric Jacobian of an arm at given joint values."""

from __future__ import annotations

import argparse
import json

import numpy as np

from umbra.connectors.errors import UserError
from umbra.modules.arm.arm_params import BUILT_IN_ARMS, load_arm
from umbra.modules.arm.dh import DHError, DHTable
from umbra.modules.arm.dls import DLSSettings
from umbra.modules.arm.jacobian import jacobian_and_pose, manipulability
from umbra.modules.geometry.transforms import xyz_rpy_deg_from_transform

NAME = "arm"
HELP = "print an arm's flange pose and geometric Jacobian at joint values"
GUIDE = "docs/guide/devices.md"  # the guide page this command's --help points to


def configure(parser: argparse.ArgumentParser) -> None:
    which = parser.add_mutually_exclusive_group()
    which.add_argument(
        "--robot", choices=sorted(BUILT_IN_ARMS), default="puma560", help="built-in arm"
    )
    which.add_argument("--dh", metavar="FILE", help="YAML DH table (see modules/arm/dh_yaml.py)")
    values = parser.add_mutually_exclusive_group(required=True)
    values.add_argument("--q", metavar="Q1,...", help="joint values, radians (metres if prismatic)")
    values.add_argument("--q-deg", metavar="Q1,...", help="joint values in degrees (revolute)")
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def _parse_q(text: str, option: str, table: DHTable) -> np.ndarray:
    try:
        q = np.array([float(part) for part in text.split(",")], dtype=float)
    except ValueError:
        raise UserError(
            f"{option} expects {table.n} comma-separated numbers, found {text!r}"
        ) from None
    if q.shape != (table.n,) or not np.all(np.isfinite(q)):
        raise UserError(
            f"{option} expects {table.n} finite values for {', '.join(table.names)}, "
            f"found {len(q)}: {text!r}"
        )
    return q


def main(args: argparse.Namespace) -> int:
    try:
        table = load_arm(args.robot, args.dh or "")
    except DHError as exc:
        raise UserError(str(exc)) from None
    if args.q is not None:
        q = _parse_q(args.q, "--q", table)
    else:
        q = _parse_q(args.q_deg, "--q-deg", table)
        q = np.where(table.revolute, np.radians(q), q)
    J, T = jacobian_and_pose(table, q)
    w = manipulability(J)
    if args.json:
        print(
            json.dumps({"T_base_flange": T.tolist(), "jacobian": J.tolist(), "manipulability": w})
        )
        return 0
    print(_text(table, q, T, J, w))
    return 0


def _matrix(rows: np.ndarray, labels: list[str] | None = None) -> list[str]:
    lines = []
    for i, row in enumerate(rows):
        label = f"{labels[i]:>3s} " if labels else "  "
        lines.append("  " + label + " ".join(f"{v:10.5f}" for v in np.round(row, 5) + 0.0))
    return lines


def _text(table: DHTable, q: np.ndarray, T: np.ndarray, J: np.ndarray, w: float) -> str:
    xyz, rpy_deg = xyz_rpy_deg_from_transform(T)
    sigma_min = float(np.linalg.svd(J, compute_uv=False)[-1])
    margin = table.limit_margin(q)
    lines = [f"arm {table.name}: {table.n} joints ({', '.join(table.names)})"]
    lines.append("q [rad]: " + " ".join(f"{v:.5f}" for v in q))
    lines += ["", "T_base_flange (metres):", *_matrix(T)]
    lines.append(
        f"  position {xyz[0]:.5f} {xyz[1]:.5f} {xyz[2]:.5f} m, "
        f"rpy_deg {rpy_deg[0]:.3f} {rpy_deg[1]:.3f} {rpy_deg[2]:.3f}"
    )
    lines += ["", "geometric Jacobian (base frame; rows [v; w]; columns " + ", ".join(table.names)]
    lines[-1] += "):"
    lines += _matrix(J, ["vx", "vy", "vz", "wx", "wy", "wz"])
    lines += ["", f"manipulability {w:.6g}, smallest singular value {sigma_min:.6g}"]
    if sigma_min < DLSSettings().eps:
        lines.append("near a singularity (DLS damping would be active)")
    outside = [n for n, m in zip(table.names, margin, strict=True) if m < 0]
    if outside:
        lines.append(f"outside joint limits: {', '.join(outside)}")
    return "\n".join(lines)
