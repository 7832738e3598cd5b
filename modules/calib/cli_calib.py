"""``umbra calib fit|zoom|pose|triangulate``: the camera calibration tools on the command line.

* ``fit CSV`` — calibrate one camera from 3-D/2-D pairs (header ``x,y,z,u,v``; metres, pixels):
  DLT, decomposition, refinement with distortion; optionally write or extend a zoom file.
* ``zoom FILE --at Z`` — the camera model interpolated at a normalized zoom.
* ``pose CSV --cameras CAMERAS.yaml`` — non-perspective n-point pose of the points' frame from
  pairs seen by one or more posed cameras (header ``camera,x,y,z,u,v``).
* ``triangulate CAMERAS.yaml --pixel A=U,V --pixel B=U,V`` — point and ray gap.

``--json`` prints one JSON object. Extrinsics are in the file's units: metres and radians.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from umbra.connectors.cli_support import print_json
from umbra.connectors.errors import UserError
from umbra.modules.calib.camera_file import load_cameras
from umbra.modules.calib.camera_model import PinholeCamera
from umbra.modules.calib.correspondences import load_correspondences
from umbra.modules.calib.errors import CalibrationError
from umbra.modules.calib.model_choice import CANDIDATES, calibrate_choosing_distortion
from umbra.modules.calib.npnp import View, solve_npnp
from umbra.modules.calib.refine import calibrate
from umbra.modules.calib.rotations import xyz_from_rotation
from umbra.modules.calib.targeting import triangulate_measured
from umbra.modules.calib.zoom_io import (
    check_writable,
    load_zoom_file,
    load_zoom_table,
    save_zoom_file,
)
from umbra.modules.calib.zoom_table import (
    EXTRINSIC_KEYS,
    INTRINSIC_KEYS,
    ZoomFile,
    ZoomSample,
    ZoomTable,
    table_from_samples,
)
from umbra.modules.geometry.rays import RayGeometryError
from umbra.modules.geometry.transforms import transform_from_xyz_rpy_deg

NAME = "calib"
HELP = "camera calibration: fit a camera, interpolate a zoom file, solve a pose, triangulate"
GUIDE = "docs/guide/calibration.md"  # the guide page this command's --help points to

DISTORTION_CHOICES = CANDIDATES


def configure(parser: argparse.ArgumentParser) -> None:
    actions = parser.add_subparsers(dest="calib_action", metavar="ACTION", required=True)

    fit = actions.add_parser(
        "fit",
        help="calibrate a camera from 3-D/2-D pairs (CSV x,y,z,u,v)",
        description="DLT with Hartley normalization, Appendix B decomposition, and refinement "
        "of all parameters with distortion. Points in metres, in the frame the extrinsics are to "
        "refer to (the camera mount, for a zoom calibration file); pixels as measured.",
    )
    fit.add_argument("correspondences", metavar="CSV", help="pairs, header x,y,z,u,v")
    fit.add_argument(
        "-o",
        "--output",
        metavar="FILE",
        help="write a zoom calibration file (.xml as Appendix D, or .yaml)",
    )
    fit.add_argument(
        "--append",
        action="store_true",
        help="add (or replace) this zoom's entry in an existing --output file",
    )
    fit.add_argument("--zoom", type=float, default=0.0, help="normalized zoom of this fit (0..1)")
    fit.add_argument("--camera", default="cam", help="camera name in the file (default cam)")
    fit.add_argument(
        "--distortion",
        choices=["auto", *sorted(DISTORTION_CHOICES)],
        default="auto",
        help="distortion terms to fit; default auto: tangential p1 p2 always, radial k1 k2 when "
        "an F test of the residuals holds them (1 %%)",
    )
    fit.add_argument("--fix-skew", action="store_true", help="hold skew (fxy) at zero")
    fit.add_argument("--linear", action="store_true", help="DLT only, no refinement")
    fit.add_argument("--json", action="store_true", help="print one JSON object")

    zoom = actions.add_parser("zoom", help="camera model at a zoom from a zoom calibration file")
    zoom.add_argument("file", metavar="FILE", help="zoom calibration file (.xml or .yaml)")
    zoom.add_argument(
        "--at", type=float, required=True, metavar="Z", help="normalized zoom 0 (wide) .. 1 (tele)"
    )
    zoom.add_argument("--camera", default="", help="camera name in the file")
    zoom.add_argument("--json", action="store_true", help="print one JSON object")

    pose = actions.add_parser(
        "pose",
        help="pose from pairs seen by posed cameras (non-perspective n-point)",
        description="Solves the pose of the points' frame in the cameras' reference frame.",
    )
    pose.add_argument("correspondences", metavar="CSV", help="pairs, header camera,x,y,z,u,v")
    pose.add_argument("--cameras", required=True, metavar="YAML", help="named, posed cameras")
    pose.add_argument(
        "--initial-xyz",
        type=float,
        nargs=3,
        metavar=("X", "Y", "Z"),
        help="a start's translation (m), tried with PnP on every view and the linear pose",
    )
    pose.add_argument(
        "--initial-rpy-deg",
        type=float,
        nargs=3,
        metavar=("R", "P", "Y"),
        help="initial roll pitch yaw (deg, fixed axes)",
    )
    pose.add_argument(
        "--pixel-sigma",
        type=float,
        default=1.0,
        metavar="PX",
        help="click noise per pixel coordinate (default 1): larger residuals are reported",
    )
    pose.add_argument("--json", action="store_true", help="print one JSON object")

    tri = actions.add_parser("triangulate", help="3-D point and ray gap from two or more pixels")
    tri.add_argument("cameras", metavar="YAML", help="named, posed cameras")
    tri.add_argument(
        "--pixel",
        action="append",
        required=True,
        metavar="CAMERA=U,V",
        help="a measured pixel in a camera's image (twice or more)",
    )
    tri.add_argument(
        "--method",
        choices=("midpoint", "least_squares", "linear"),
        default="midpoint",
        help="midpoint (Duda-Hart, two cameras), least_squares "
        "(any number) or linear (Rochester pseudo-inverse)",
    )
    tri.add_argument("--json", action="store_true", help="print one JSON object")


def main(args: argparse.Namespace) -> int:
    action = {"fit": _fit, "zoom": _zoom, "pose": _pose, "triangulate": _triangulate}
    try:
        return action[args.calib_action](args)
    except (CalibrationError, RayGeometryError, ValueError) as error:
        raise UserError(str(error)) from None


# -- shared formatting ---------------------------------------------------------------------------


def _camera_sample(camera: PinholeCamera, zoom: float) -> ZoomSample:
    f = camera.intrinsics
    intrinsics = [f.fx, f.fy, f.skew, f.u0, f.v0, *camera.distortion[:4]]
    extrinsics = [*camera.d, *xyz_from_rotation(camera.R)]
    return ZoomSample(zoom, np.array(intrinsics, float), np.array(extrinsics, float))


def _describe_sample(sample: ZoomSample) -> list[str]:
    i = dict(zip(INTRINSIC_KEYS, sample.intrinsics, strict=True))
    e = dict(zip(EXTRINSIC_KEYS, sample.extrinsics, strict=True))
    return [
        f"  intrinsics  fx {i['fx']:.2f}  fy {i['fy']:.2f}  skew {i['skew']:.2f}  "
        f"u0 {i['u0']:.2f}  v0 {i['v0']:.2f}  [px]",
        f"  distortion  k1 {i['k1']:.5g}  k2 {i['k2']:.5g}  p1 {i['p1']:.5g}  p2 {i['p2']:.5g}",
        f"  extrinsics  d [{e['dx']:.4f}, {e['dy']:.4f}, {e['dz']:.4f}] m   "
        f"theta x y z [{e['rx']:.4f}, {e['ry']:.4f}, {e['rz']:.4f}] rad "
        f"([{np.degrees(e['rx']):.2f}, {np.degrees(e['ry']):.2f}, {np.degrees(e['rz']):.2f}] deg)",
    ]


# -- fit -----------------------------------------------------------------------------------------


def _fit(args: argparse.Namespace) -> int:
    if not 0.0 <= args.zoom <= 1.0:
        raise UserError(f"--zoom must be a normalized zoom in 0..1, got {args.zoom}")
    if args.append and not args.output:
        raise UserError("--append needs --output FILE")
    if args.output:
        check_writable(Path(args.output), "--output")
    data = load_correspondences(args.correspondences)
    choice = None
    if args.distortion == "auto" and not args.linear:
        result, choice = calibrate_choosing_distortion(data.points, data.pixels, args.fix_skew)
        model = choice.chosen
    else:
        model = "k1k2p1p2" if args.distortion == "auto" else args.distortion
        result = calibrate(
            data.points,
            data.pixels,
            distortion_terms=DISTORTION_CHOICES[model],
            fix_skew=args.fix_skew,
            refine=not args.linear,
        )
    chosen = {
        "distortion_model": "none (DLT)" if args.linear else model,
        "why": choice.reason if choice else "given by --distortion",
    }
    sample = _camera_sample(result.camera, args.zoom)
    P = result.camera.camera_matrix()
    if args.output:
        _write_fit(Path(args.output), args.camera, sample, args.append)
    if args.json:
        out = sample.as_dict()
        del out["zoom"]
        print_json(
            {
                "rms_px": result.rms_px,
                **out,
                "camera_matrix": P.tolist(),
                "linear_rms_px": result.linear_rms_px,
                "points": len(data.points),
                **chosen,
                "radial_test": {"F": choice.radial_f, "p_value": choice.radial_p_value}
                if choice
                else {},
                "rms_px_by_model": choice.rms_px if choice else {},
                "standard_errors": result.standard_errors,
                "interval_95": result.interval_95() if result.standard_errors else {},
            }
        )
        return 0
    kind = "DLT only" if args.linear else f"refined, distortion {model}"
    print(f"fit of {len(data.points)} pairs from {args.correspondences} ({kind})")
    if choice:
        print(f"  {choice.reason}")
    print(f"  reprojection RMS {result.rms_px:.4f} px (linear DLT {result.linear_rms_px:.4f} px)")
    print("\n".join(_describe_sample(sample)))
    if result.standard_errors:
        print("  standard errors (1 sigma; px, unitless, rad about the fitted R, m):")
        print("    " + "  ".join(f"{k} {v:.4g}" for k, v in result.standard_errors.items()))
        print("  95 % intervals (+-, Student's t at the residuals' degrees of freedom):")
        print("    " + "  ".join(f"{k} {v:.4g}" for k, v in result.interval_95().items()))
    print("  camera matrix K [R | d]:")
    for row in P:
        print("    [" + "  ".join(f"{v:14.6g}" for v in row) + "]")
    if args.output:
        print(f"wrote {args.output} (camera {args.camera!r}, zoom {args.zoom:g})")
    return 0


def _write_fit(path: Path, camera: str, sample: ZoomSample, append: bool) -> None:
    tables: list[ZoomTable] = []
    comment, recorded = f"umbra calib fit of camera {camera}", str(path)
    if append and path.exists():
        existing = load_zoom_file(path)
        tables, comment, recorded = list(existing.cameras), existing.comment, existing.recorded_path
    for index, table in enumerate(tables):
        if table.name == camera:
            rows = [table.row(i) for i in range(len(table)) if table.zooms[i] != sample.zoom]
            tables[index] = table_from_samples(camera, [*rows, sample])
            break
    else:
        tables.append(table_from_samples(camera, [sample]))
    save_zoom_file(path, ZoomFile(tuple(tables), comment, recorded))


# -- zoom ----------------------------------------------------------------------------------------


def _zoom(args: argparse.Namespace) -> int:
    table = load_zoom_table(args.file, args.camera or None)
    sample = table.sample(args.at)
    if args.json:
        print_json(sample.as_dict())
        return 0
    print(
        f"camera {table.name!r} at zoom {args.at:g} (linear interpolation; "
        f"{len(table)} entries from {table.zooms[0]:g} to {table.zooms[-1]:g} in {args.file})"
    )
    print("\n".join(_describe_sample(sample)))
    return 0


# -- pose ----------------------------------------------------------------------------------------


def _pose(args: argparse.Namespace) -> int:
    if not (np.isfinite(args.pixel_sigma) and args.pixel_sigma > 0):
        raise UserError(f"--pixel-sigma: expected a click noise > 0 px, got {args.pixel_sigma}")
    cameras = load_cameras(args.cameras)
    data = load_correspondences(args.correspondences, with_camera=True)
    for name, line in zip(data.cameras, data.lines, strict=True):
        if name not in cameras:
            known = ", ".join(sorted(cameras))
            raise UserError(
                f"{args.correspondences}:{line}: error: unknown camera {name!r} (cameras file "
                f"{args.cameras} has {known})"
            )
    camera_of = np.array(data.cameras)
    seen = set(data.cameras)
    names = [n for n in cameras if n in seen]
    views = []
    for name in names:
        mask = camera_of == name
        views.append(View(cameras[name], data.points[mask], data.pixels[mask]))
    initial = None
    if args.initial_xyz is not None or args.initial_rpy_deg is not None:
        initial = transform_from_xyz_rpy_deg(
            args.initial_xyz or [0.0, 0.0, 0.0], args.initial_rpy_deg or [0.0, 0.0, 0.0]
        )
    result = solve_npnp(views, initial, pixel_sigma=args.pixel_sigma)
    rpy_deg = np.degrees(xyz_from_rotation(result.R))
    per_camera = {
        name: float(np.sqrt(np.mean(np.sum(r**2, axis=1))))
        for name, r in zip(names, result.residuals, strict=True)
    }
    if args.json:
        print_json(
            {
                "T": result.T.tolist(),
                "xyz": result.d.tolist(),
                "rpy_deg": rpy_deg.tolist(),
                "rms_px": result.rms_px,
                "iterations": result.iterations,
                "points": len(data.points),
                "cameras": per_camera,
                "start": result.start,
                "warnings": list(result.warnings),
            }
        )
        return 0
    print(
        f"pose of the points' frame in the reference frame ({len(data.points)} pairs, "
        f"{len(views)} cameras, {result.iterations} Gauss-Newton iterations)"
    )
    print(f"  xyz      [{result.d[0]:.5f}, {result.d[1]:.5f}, {result.d[2]:.5f}] m")
    print(f"  rpy_deg  [{rpy_deg[0]:.4f}, {rpy_deg[1]:.4f}, {rpy_deg[2]:.4f}] (fixed axes x, y, z)")
    print(
        f"  reprojection RMS {result.rms_px:.4f} px: "
        + ", ".join(f"{name} {rms:.3f}" for name, rms in per_camera.items())
    )
    print(f"  from {result.start} (the lowest of every start's minimum)")
    for warning in result.warnings:
        print(f"  warning: {warning}")
    return 0


# -- triangulate ---------------------------------------------------------------------------------


def _parse_pixel(text: str) -> tuple[str, np.ndarray]:
    name, sep, values = text.partition("=")
    parts = values.split(",")
    try:
        if not sep or not name or len(parts) != 2:
            raise ValueError
        return name.strip(), np.array([float(p) for p in parts])
    except ValueError:
        raise UserError(f"--pixel expects CAMERA=U,V, found {text!r}") from None


def _triangulate(args: argparse.Namespace) -> int:
    cameras = load_cameras(args.cameras)
    pixels = [_parse_pixel(p) for p in args.pixel]
    if len(pixels) < 2:
        raise UserError("triangulate needs --pixel for at least two cameras")
    for name, _ in pixels:
        if name not in cameras:
            raise UserError(
                f"unknown camera {name!r}; {args.cameras} has {', '.join(sorted(cameras))}"
            )
    # RayGeometryError (a pixel outside its lens model, degenerate rays) becomes a UserError.
    result, depths = triangulate_measured(
        [cameras[name] for name, _ in pixels], [uv for _, uv in pixels], args.method
    )
    if args.json:
        print_json(
            {
                "point": np.asarray(result.point).tolist(),
                "gap": float(result.gap),
                "method": args.method,
                "depths": depths,
            }
        )
        return 0
    x, y, z = result.point
    print(f"point  [{x:.5f}, {y:.5f}, {z:.5f}] m (reference frame of {args.cameras})")
    print(f"gap    {float(result.gap) * 1000:.3f} mm ({args.method})")
    print("depth  " + ", ".join(f"{n} {d:.4f} m" for (n, _), d in zip(pixels, depths, strict=True)))
    if min(depths) <= 0:
        print("warning: the point is behind a camera; the pixels probably do not match")
    return 0
