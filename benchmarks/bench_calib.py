"""Calibration math against OpenCV, all on the same noisy synthetic data, in one run.

1. Camera calibration from a 3-D rig: DLT + refinement (``umbra.modules.calib.refine.calibrate``)
   against ``cv2.calibrateCamera`` (one view of a non-planar rig, CALIB_USE_INTRINSIC_GUESS,
   CALIB_FIX_K3). Fit RMS, error of held-out projections against the true camera, parameter
   errors, time. Goal: at least as accurate as OpenCV.
2. Single-camera pose: ``solve_npnp`` with one view against ``cv2.solvePnP`` ITERATIVE and SQPNP:
   rotation / translation error and time per call.
3. Several cameras with known, different poses (rays that do not meet at one point): the
   non-perspective n-point solution with all rays against single-camera SQPnP, which can only use
   one view's rays; pose error against pixel noise.
4. Triangulation of a stereo pair: Duda-Hart midpoint, least squares, Rochester pseudo-inverse
   against ``cv2.triangulatePoints``: 3-D error and time per point.
5. Point undistortion: ours (Newton) against ``cv2.undistortPoints`` (fixed-point): residual
   and time.
6. Zoom interpolation on the report's own table (Appendix D): leave-one-out error of the report's
   linear interpolation against geometric and log-PCHIP interpolation of the focal length.
7-9. (:mod:`benchmarks.calib_bundle`) nPnP's time against a plain bundle (SQPnP + scipy) at the
   same accuracy; planar targets (global minimum or a named rival); the coverage of the stated
   95 % intervals of ``calib fit`` against ``cv2.calibrateCameraExtended``'s, on a 60-point rig at
   0.3 px and on a weak one (40 points at 1 px: the principal point known to about 25 px, where
   first-order intervals, OpenCV's too, hold it 86 % of the time).

    python benchmarks/bench_calib.py [--quick]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.calib_bundle import bench_bundle, bench_coverage, bench_planar
from benchmarks.common import table, write_results
from umbra.modules.calib.camera_model import Intrinsics, PinholeCamera
from umbra.modules.calib.distortion import distort_points, undistort_points
from umbra.modules.calib.dlt import rms
from umbra.modules.calib.npnp import View, solve_npnp
from umbra.modules.calib.refine import calibrate
from umbra.modules.calib.rotations import rotation_from_vector, vector_from_rotation
from umbra.modules.calib.synthetic import (
    TYPICAL_DISTORTION,
    TYPICAL_INTRINSICS,
    panel_rig,
    random_pose,
    ring_of_cameras,
)
from umbra.modules.calib.zoom_interp import leave_one_out
from umbra.modules.calib.zoom_io import load_zoom_table
from umbra.modules.geometry.rays import triangulate_pixels

REPORT_FILE = Path(__file__).resolve().parent.parent / "modules" / "calib" / "data" / "zoom_cam.xml"


def angle_deg(R_a: np.ndarray, R_b: np.ndarray) -> float:
    return float(np.degrees(np.linalg.norm(vector_from_rotation(R_a.T @ R_b))))


def timed(fn, repeat: int = 1):
    start = time.perf_counter()
    for _ in range(repeat):
        out = fn()
    return out, (time.perf_counter() - start) / repeat


# -- 1. calibration ------------------------------------------------------------------------------


#: Scenarios: (name, focal scale, rig distance m, distortion scale). "tele" is the report's
#: zoom camera near zoom 0.3 (fx ~ 2300 px), with the rig moved back to fill the image.
SCENARIOS = (("wide", 1.0, 1.05, 1.0), ("tele", 2.8, 3.0, 0.3))


def random_rig_camera(
    rng: np.random.Generator, focal_scale: float, distance: float, distortion_scale: float
) -> PinholeCamera:
    f = TYPICAL_INTRINSICS
    intrinsics = Intrinsics(
        f.fx * focal_scale * rng.uniform(0.9, 1.1),
        f.fy * focal_scale * rng.uniform(0.9, 1.1),
        0.0,
        f.u0 + rng.uniform(-15, 15),
        f.v0 + rng.uniform(-15, 15),
    )
    distortion = TYPICAL_DISTORTION * distortion_scale * rng.uniform(0.7, 1.3, 4)
    R = rotation_from_vector(rng.uniform(-0.15, 0.15, 3))
    d = np.array(
        [rng.uniform(-0.05, 0.05), rng.uniform(-0.05, 0.05), distance * rng.uniform(0.9, 1.1)]
    )
    return PinholeCamera(intrinsics, R, d, distortion)


def held_out_points() -> np.ndarray:
    return panel_rig(columns=9, rows=7, depths=(-0.05, 0.1, 0.25, 0.35), pitch=0.07)


#: Summary key and column title of each calibration figure, in table order.
CALIBRATION_COLUMNS = (
    ("fit_rms_px", "fit RMS px"),
    ("held_out_rms_px_median", "held-out px"),
    ("held_out_rms_px_p90", "held-out p90"),
    ("fx_error_pct_median", "fx err %"),
    ("principal_point_error_px_median", "pp err px"),
    ("k1_error_median", "k1 err"),
    ("time_ms_median", "time ms"),
)


def bench_calibration(trials: int, noise_px: float, seed: int) -> dict:
    return {
        name: bench_calibration_scenario(trials, noise_px, seed + i, name, *settings)
        for i, (name, *settings) in enumerate(SCENARIOS)
    }


def bench_calibration_scenario(
    trials: int,
    noise_px: float,
    seed: int,
    scenario: str,
    focal_scale: float,
    distance: float,
    distortion_scale: float,
) -> dict:
    rng = np.random.default_rng(seed)
    points = panel_rig()
    check = held_out_points()
    methods = (
        "ours (report model)",
        "ours (skew fixed 0)",
        "cv2 (nominal guess)",
        "cv2 (DLT guess)",
    )
    stats = {
        m: {"fit_rms": [], "held_out": [], "fx": [], "pp": [], "k1": [], "time": []}
        for m in methods
    }
    nominal = np.array([[800.0, 0, 320], [0, 800.0, 240], [0, 0, 1]])
    flags = cv2.CALIB_USE_INTRINSIC_GUESS | cv2.CALIB_FIX_K3
    for _ in range(trials):
        truth = random_rig_camera(rng, focal_scale, distance, distortion_scale)
        pixels = truth.project(points) + rng.normal(0, noise_px, (len(points), 2))
        expected = truth.project(check)
        for name, fix_skew in ((methods[0], False), (methods[1], True)):
            result, seconds = timed(lambda fs=fix_skew, u=pixels: calibrate(points, u, fix_skew=fs))
            cam = result.camera
            _record(
                stats[name],
                result.rms_px,
                cam.project(check) - expected,
                cam.intrinsics,
                cam.distortion[0],
                truth,
                seconds,
            )
        dlt_guess = calibrate(points, pixels, refine=False).camera.K
        dlt_guess[0, 1] = 0.0  # OpenCV's model has no skew
        for name, guess in ((methods[2], nominal), (methods[3], dlt_guess)):

            def run_cv(g=guess, u=pixels):
                return cv2.calibrateCamera(
                    [points.astype(np.float32)],
                    [u.astype(np.float32)],
                    (640, 480),
                    g.copy(),
                    None,
                    flags=flags,
                )

            (rms_cv, K, dist, rvecs, tvecs), seconds = timed(run_cv)
            projected, _ = cv2.projectPoints(check, rvecs[0], tvecs[0], K, dist)
            _record(
                stats[name],
                rms_cv,
                projected.reshape(-1, 2) - expected,
                Intrinsics.from_matrix(K),
                dist.ravel()[0],
                truth,
                seconds,
            )
    rows, summary = [], {}
    baseline = np.median(stats[methods[2]]["held_out"])
    for name in methods:
        s = {k: np.asarray(v) for k, v in stats[name].items()}
        summary[name] = {
            "fit_rms_px": float(np.median(s["fit_rms"])),
            "held_out_rms_px_median": float(np.median(s["held_out"])),
            "held_out_rms_px_p90": float(np.percentile(s["held_out"], 90)),
            "fx_error_pct_median": float(np.median(s["fx"])),
            "principal_point_error_px_median": float(np.median(s["pp"])),
            "k1_error_median": float(np.median(s["k1"])),
            "time_ms_median": float(np.median(s["time"]) * 1e3),
        }
        r = summary[name]
        ratio = r["held_out_rms_px_median"] / baseline
        rows.append([name, *(r[key] for key, _ in CALIBRATION_COLUMNS), ratio])
    print(
        f"\n1. calibration ({scenario}: fx ~ {TYPICAL_INTRINSICS.fx * focal_scale:.0f} px, rig at "
        f"{distance} m), 3-D rig of {len(points)} points, {noise_px} px noise, {trials} random "
        f"cameras (held-out: {len(check)} points vs the true camera)"
    )
    header = ["method", *(title for _, title in CALIBRATION_COLUMNS), "held-out / cv2"]
    print(table(rows, header))
    return {
        "noise_px": noise_px,
        "trials": trials,
        "points": len(points),
        "focal_px": TYPICAL_INTRINSICS.fx * focal_scale,
        "rig_distance_m": distance,
        "methods": summary,
    }


def _record(s, fit_rms, diff, intrinsics, k1, truth, seconds) -> None:
    s["fit_rms"].append(float(fit_rms))
    s["held_out"].append(rms(np.linalg.norm(diff, axis=1)))
    s["fx"].append(abs(intrinsics.fx / truth.intrinsics.fx - 1) * 100)
    s["pp"].append(
        float(np.hypot(intrinsics.u0 - truth.intrinsics.u0, intrinsics.v0 - truth.intrinsics.v0))
    )
    s["k1"].append(abs(float(k1) - truth.distortion[0]))
    s["time"].append(seconds)


# -- 2. single-camera pose -----------------------------------------------------------------------


def bench_single_pose(trials: int, noise_px: float, seed: int) -> dict:
    rng = np.random.default_rng(seed)
    camera = PinholeCamera(TYPICAL_INTRINSICS, np.eye(3), np.zeros(3))
    K = camera.K
    methods = ("ours nPnP (1 view)", "cv2 ITERATIVE", "cv2 SQPNP")
    errors = {m: {"rot": [], "trans": [], "time": []} for m in methods}
    for _ in range(trials):
        R, d = random_pose(rng, angle=0.6, offset=0.15)
        d = d + np.array([0.0, 0.0, 1.2])
        points = rng.uniform(-0.2, 0.2, (10, 3))
        pixels = camera.project(points @ R.T + d) + rng.normal(0, noise_px, (10, 2))
        result, seconds = timed(lambda p=points, u=pixels: solve_npnp([View(camera, p, u)]), 3)
        _pose_errors(errors[methods[0]], result.R, result.d, R, d, seconds)
        for name, flag in ((methods[1], cv2.SOLVEPNP_ITERATIVE), (methods[2], cv2.SOLVEPNP_SQPNP)):
            (_, rvec, tvec), seconds = timed(
                lambda p=points, u=pixels, f=flag: cv2.solvePnP(p, u, K, None, flags=f), 3
            )
            _pose_errors(
                errors[name], rotation_from_vector(rvec.ravel()), tvec.ravel(), R, d, seconds
            )
    return _pose_table(
        errors,
        methods,
        f"\n2. single-camera pose, 10 points, {noise_px} px noise, {trials} random poses",
        {"noise_px": noise_px, "trials": trials},
        baseline=methods[1],
    )


def _pose_errors(s, R_est, d_est, R, d, seconds) -> None:
    s["rot"].append(angle_deg(R_est, R))
    s["trans"].append(float(np.linalg.norm(d_est - d) * 1000))
    s["time"].append(seconds)


def _pose_table(errors, methods, title, info, baseline) -> dict:
    rows, summary = [], {}
    base_time = np.median(errors[baseline]["time"])
    base_rot = np.median(errors[baseline]["rot"])
    for name in methods:
        e = errors[name]
        summary[name] = {
            "rotation_error_deg_median": float(np.median(e["rot"])),
            "translation_error_mm_median": float(np.median(e["trans"])),
            "time_us_median": float(np.median(e["time"]) * 1e6),
        }
        r = summary[name]
        rows.append(
            [
                name,
                r["rotation_error_deg_median"],
                r["translation_error_mm_median"],
                r["rotation_error_deg_median"] / base_rot,
                r["time_us_median"],
                r["time_us_median"] / (base_time * 1e6),
            ]
        )
    print(title)
    print(
        table(
            rows,
            ["method", "rot err deg", "trans err mm", "rot err ratio", "time us", "time ratio"],
        )
    )
    return {**info, "methods": summary, "baseline": baseline}


# -- 3. multi-camera non-perspective pose --------------------------------------------------------


def bench_multi_pose(trials: int, noises: tuple[float, ...], seed: int) -> dict:
    rng = np.random.default_rng(seed)
    cameras = ring_of_cameras(4, 2.0, spread=0.8)
    per_view = 4
    rows, results = [], []
    for noise in noises:
        rot_all, rot_one, trans_all, trans_one = [], [], [], []
        for _ in range(trials):
            R, d = random_pose(rng, angle=0.5, offset=0.1)
            views = []
            for camera in cameras:
                points = rng.uniform(-0.15, 0.15, (per_view, 3))
                pixels = camera.project(points @ R.T + d)
                views.append(View(camera, points, pixels + rng.normal(0, noise, pixels.shape)))
            all_rays = solve_npnp(views)
            rot_all.append(angle_deg(all_rays.R, R))
            trans_all.append(float(np.linalg.norm(all_rays.d - d) * 1000))
            # Single-camera PnP can only use one view: each view's answer, moved to the object
            # frame with the camera's known pose; the median over the views.
            view_rot, view_trans = [], []
            for view in views:
                _, rvec, tvec = cv2.solvePnP(
                    view.points, view.pixels, view.camera.K, None, flags=cv2.SOLVEPNP_SQPNP
                )
                R_one = view.camera.R.T @ rotation_from_vector(rvec.ravel())
                d_one = view.camera.R.T @ (tvec.ravel() - view.camera.d)
                view_rot.append(angle_deg(R_one, R))
                view_trans.append(float(np.linalg.norm(d_one - d) * 1000))
            rot_one.append(np.median(view_rot))
            trans_one.append(np.median(view_trans))
        entry = {
            "noise_px": noise,
            "npnp_rotation_deg": float(np.median(rot_all)),
            "npnp_translation_mm": float(np.median(trans_all)),
            "single_view_sqpnp_rotation_deg": float(np.median(rot_one)),
            "single_view_sqpnp_translation_mm": float(np.median(trans_one)),
        }
        results.append(entry)
        rows.append(
            [
                noise,
                entry["npnp_rotation_deg"],
                entry["single_view_sqpnp_rotation_deg"],
                entry["npnp_rotation_deg"] / entry["single_view_sqpnp_rotation_deg"],
                entry["npnp_translation_mm"],
                entry["single_view_sqpnp_translation_mm"],
                entry["npnp_translation_mm"] / entry["single_view_sqpnp_translation_mm"],
            ]
        )
    print(
        f"\n3. non-perspective pose: {len(cameras)} cameras 2 m away, {per_view} points each, "
        f"{trials} random poses per noise level (medians)"
    )
    print(
        table(
            rows,
            [
                "noise px",
                "nPnP rot deg",
                "1-view rot deg",
                "ratio",
                "nPnP mm",
                "1-view mm",
                "ratio",
            ],
        )
    )
    return {
        "cameras": len(cameras),
        "points_per_view": per_view,
        "trials": trials,
        "levels": results,
    }


# -- 4. triangulation ----------------------------------------------------------------------------


def bench_triangulation(count: int, noise_px: float, seed: int) -> dict:
    rng = np.random.default_rng(seed)
    K = TYPICAL_INTRINSICS.matrix()
    cams = []
    for yaw, centre in ((0.12, [-0.3, 0.0, 0.0]), (-0.12, [0.3, 0.02, 0.0])):
        R = rotation_from_vector([0.0, yaw, 0.0])
        cams.append(K @ np.hstack([R, (-R @ np.array(centre))[:, None]]))
    X = rng.uniform([-0.5, -0.4, 1.5], [0.5, 0.4, 3.5], (count, 3))
    uv = []
    for P in cams:
        h = np.hstack([X, np.ones((count, 1))]) @ P.T
        uv.append(h[:, :2] / h[:, 2:] + rng.normal(0, noise_px, (count, 2)))
    rows, summary = [], {}

    def cv_tri():
        h = cv2.triangulatePoints(cams[0], cams[1], uv[0].T, uv[1].T)
        return (h[:3] / h[3]).T

    base, base_time = timed(cv_tri)
    base_error = rms(np.linalg.norm(base - X, axis=1)) * 1000
    candidates = {"cv2.triangulatePoints": lambda: base}
    for method in ("midpoint", "least_squares", "linear"):
        candidates[f"ours {method}"] = lambda m=method: triangulate_pixels(cams, uv, m).point
    for name, fn in candidates.items():
        if name == "cv2.triangulatePoints":
            points, seconds = base, base_time
        else:
            points, seconds = timed(fn)
        error = rms(np.linalg.norm(points - X, axis=1)) * 1000
        summary[name] = {"rms_error_mm": error, "time_us_per_point": seconds / count * 1e6}
        rows.append([name, error, error / base_error, seconds / count * 1e6, seconds / base_time])
    print(
        f"\n4. triangulation, stereo pair 0.6 m apart, {count} points 1.5-3.5 m away, "
        f"{noise_px} px noise"
    )
    print(table(rows, ["method", "RMS err mm", "err ratio", "time us/pt", "time ratio"]))
    return {"points": count, "noise_px": noise_px, "methods": summary}


# -- 5. undistortion -----------------------------------------------------------------------------


def bench_undistort(count: int, seed: int) -> dict:
    rng = np.random.default_rng(seed)
    K = TYPICAL_INTRINSICS.matrix()
    dist = np.array([-0.35, 0.15, 0.001, -0.001])
    pixels = rng.uniform([0, 0], [640, 480], (count, 2))
    ours, t_ours = timed(lambda: undistort_points(pixels, K, dist), 3)
    theirs, t_cv = timed(
        lambda: cv2.undistortPoints(pixels[:, None, :], K, dist, None, K).reshape(-1, 2), 3
    )
    res_ours = np.abs(distort_points(ours, K, dist) - pixels).max()
    res_cv = np.abs(distort_points(theirs, K, dist) - pixels).max()
    print(
        f"\n5. point undistortion, {count} pixels over a 640x480 image, k1 = -0.35 "
        "(residual = max |distort(undistort(p)) - p|)"
    )
    print(
        table(
            [
                ["ours (Newton)", float(res_ours), t_ours / count * 1e6, t_ours / t_cv],
                ["cv2.undistortPoints", float(res_cv), t_cv / count * 1e6, 1.0],
            ],
            ["method", "residual px", "time us/pt", "time ratio"],
        )
    )
    return {
        "points": count,
        "ours_residual_px": float(res_ours),
        "cv2_residual_px": float(res_cv),
        "ours_time_us_per_point": t_ours / count * 1e6,
        "cv2_time_us_per_point": t_cv / count * 1e6,
    }


# -- 6. zoom interpolation -----------------------------------------------------------------------


#: the project's rule (the report's linear one) and two focal-length laws it is compared with
METHODS = ("linear", "geometric", "pchip")


def _focal_law(zooms: np.ndarray, focal: np.ndarray, z: float, method: str) -> float:
    """A comparison law for the focal length: linear in ``log f`` or a PCHIP through ``log f``."""
    from scipy.interpolate import PchipInterpolator

    if method == "geometric" or len(zooms) < 3:
        return float(np.exp(np.interp(z, zooms, np.log(focal))))
    return float(np.exp(PchipInterpolator(zooms, np.log(focal))(z)))


def _leave_one_out(table_, method: str) -> dict:
    result = leave_one_out(table_.zooms, table_.intrinsics, table_.extrinsics)
    if method == "linear":
        return result
    for column, key in ((0, "fx_rel"), (1, "fy_rel")):
        errors = []
        for i in range(1, len(table_.zooms) - 1):
            keep = np.arange(len(table_.zooms)) != i
            focal = table_.intrinsics[:, column]
            got = _focal_law(table_.zooms[keep], focal[keep], table_.zooms[i], method)
            errors.append(got / focal[i] - 1.0)
        result[key] = np.asarray(errors)
    return result


def bench_zoom() -> dict:
    table_ = load_zoom_table(REPORT_FILE)
    results = {m: _leave_one_out(table_, m) for m in METHODS}
    zooms = results["linear"]["zoom"]
    rows = []
    for i, z in enumerate(zooms):
        rows.append(
            [f"{z:g}"]
            + [100 * results[m]["fx_rel"][i] for m in METHODS]
            + [100 * results[m]["fy_rel"][i] for m in METHODS]
        )
    for label, fn in (("max |err|", lambda a: np.max(np.abs(a))), ("RMS", rms)):
        rows.append(
            [label]
            + [100 * fn(results[m]["fx_rel"]) for m in METHODS]
            + [100 * fn(results[m]["fy_rel"]) for m in METHODS]
        )
    print(
        "\n6. zoom interpolation, leave-one-out on the report's table (Appendix D): relative "
        "focal-length error % when each interior zoom is predicted from the others"
    )
    print(
        table(rows, ["held-out zoom"] + [f"fx {m}" for m in METHODS] + [f"fy {m}" for m in METHODS])
    )
    summary = {}
    for m in METHODS:
        r = results[m]
        summary[m] = {
            "fx_rel_error_max_pct": float(100 * np.max(np.abs(r["fx_rel"]))),
            "fx_rel_error_rms_pct": float(100 * rms(r["fx_rel"])),
            "fy_rel_error_max_pct": float(100 * np.max(np.abs(r["fy_rel"]))),
            "fy_rel_error_rms_pct": float(100 * rms(r["fy_rel"])),
            "fx_rel_error_pct_by_zoom": dict(
                zip(map(str, zooms), map(float, 100 * r["fx_rel"]), strict=True)
            ),
            "principal_point_error_px_rms": rms(r["principal_px"]),
        }
    return {"file": str(REPORT_FILE.name), "held_out_zooms": zooms.tolist(), "methods": summary}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer trials (about 10 s)")
    args = parser.parse_args()
    quick = args.quick
    results = {
        "calibration": bench_calibration(8 if quick else 60, 0.3, seed=1),
        "single_camera_pose": bench_single_pose(30 if quick else 300, 0.5, seed=2),
        "multi_camera_pose": bench_multi_pose(10 if quick else 100, (0.1, 0.3, 1.0, 3.0), seed=3),
        "triangulation": bench_triangulation(2000 if quick else 20000, 0.5, seed=4),
        "undistortion": bench_undistort(5000 if quick else 50000, seed=5),
        "zoom_interpolation": bench_zoom(),
        "npnp_against_bundle": bench_bundle(30 if quick else 300, seed=6),
        "planar_targets": bench_planar(60 if quick else 600, seed=7),
        "stated_error_coverage": bench_coverage(100 if quick else 800, seed=8),
        "stated_error_coverage_weak_rig": bench_coverage(
            100 if quick else 800, seed=9, points=40, sigma_px=1.0, rig_seed=4
        ),
    }
    path = write_results("calib", results, quick=quick)
    print(f"\nwrote {path}")


if __name__ == "__main__":
    main()
