"""Active Sketch over randomized, seeded scenes with the operator's clicks simulated with pixel
noise: targeting error at 1-3 m (fixed wide cameras, the same-run baseline, against cameras aimed
by the PTUs and zoomed), success per macro, and the VCR's pause, jerk, retrace and transition
figures against a step-velocity VCR (the same-run baseline: no ramps).

    python benchmarks/bench_sketch.py [--quick] [--scenes N] [--seed S]

Snapshots are taken without rendering (the clicks come from the true features projected through
the snapshot's camera models, plus noise); rendering is measured by the tests, not here.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.common import percentiles, table, write_results
from umbra.modules.sketch.rig import default_rig
from umbra.modules.sketch.session import SketchSession
from umbra.modules.sketch.stereo import StereoNoise, StereoPair
from umbra.modules.trajectory.player import PathPlayer
from umbra.modules.world.scene_objects import SketchScene

CLICK_PX = 0.5
MACROS = ("grab_pipe", "move_around_axis", "surface_scan", "follow_perimeter", "place_device")


def _clicks(session: SketchSession, points: np.ndarray, rng: np.random.Generator):
    """Operator's clicks: image a with noise; image b on the epipolar line (the page's
    constraint) with noise along it."""
    a, b = session.true_pixels(points)
    a = a + rng.normal(0.0, CLICK_PX, a.shape)
    pair = StereoPair.from_snapshot(session.snapshots[list(session.snapshots)[-1]])
    along = pair.epipolar_line_b(a)[..., :2] @ np.array([[0.0, 1.0], [-1.0, 0.0]])
    return a, b + rng.normal(0.0, CLICK_PX, (len(points), 1)) * along


# -- targeting ----------------------------------------------------------------------------------
def targeting(n_points: int, seed: int) -> dict:
    rng = np.random.default_rng(seed)
    rig = default_rig()
    mast = 0.5 * (rig[0].T_base_ptu[:3, 3] + rig[1].T_base_ptu[:3, 3])
    axis = rig[0].T_base_ptu[:3, 2]  # the units' home view direction
    out = {}
    for distance in (1.0, 1.5, 2.0, 2.5, 3.0):
        errors = {"fixed wide": [], "aimed zoom 0.3": [], "aimed zoom 0.4": []}
        sigmas = {k: [] for k in errors}
        for _ in range(n_points):
            direction = axis + rng.normal(0.0, 0.08, 3)
            point = mast + distance * direction / np.linalg.norm(direction)
            for key in errors:
                session = SketchSession(SketchScene.nominal(), seed=int(rng.integers(1 << 30)))
                if key != "fixed wide":
                    session.aim(point, zoom=float(key.split()[-1]))
                session.snapshot(render=False)
                a, b = _clicks(session, point[None, :], rng)
                if not _in_view(a, b):
                    continue
                pair = StereoPair.from_snapshot(session.snapshots["snap1"])
                X, cov, _ = pair.triangulate_with_covariance(a[0], b[0], StereoNoise(CLICK_PX))
                errors[key].append(float(np.linalg.norm(X - point)) * 1e3)
                sigmas[key].append(float(np.sqrt(np.trace(cov))) * 1e3)
        out[f"{distance:.1f} m"] = {
            k: {
                **percentiles(v, (50, 95)),
                "n": len(v),
                "predicted_sigma_mm_p50": float(np.median(sigmas[k])) if sigmas[k] else None,
            }
            for k, v in errors.items()
            if v
        }
    return out


def _in_view(a: np.ndarray, b: np.ndarray) -> bool:
    return bool(np.all((a >= 0) & (a <= [640, 480])) and np.all((b >= 0) & (b <= [640, 480])))


# -- macros -------------------------------------------------------------------------------------
def _session(seed: int) -> tuple[SketchSession, np.random.Generator]:
    scene = SketchScene.random(np.random.default_rng(seed))
    return SketchSession(scene, seed=seed), np.random.default_rng(seed + 1)


def _place(session, rng, kind, points, aim_at, zoom=0.3):
    session.aim(aim_at, zoom=zoom)
    session.snapshot(render=False)
    a, b = _clicks(session, points, rng)
    return session.place(kind, a, b)


def run_macro(macro: str, seed: int) -> dict:
    s, rng = _session(seed)
    scene = s.scene
    try:
        if macro == "grab_pipe":
            prim = _place(s, rng, "line", scene.pipe.ends, scene.pipe.center)
        elif macro == "move_around_axis":
            d = scene.door
            ends = np.stack(
                [d.handle_center - 0.05 * d.handle_axis, d.handle_center + 0.05 * d.handle_axis]
            )
            handle = _place(s, rng, "line", ends, d.handle_center)
            grab = s.plan("grab_pipe", handle.primitive_id)
            if not grab.ok:
                return {"ok": False, "why": f"handle grab refused: {grab.reason}"}
            s.play(grab.path_id)
            prim = _place(
                s,
                rng,
                "line",
                np.stack([d.hinge_top, d.hinge]),
                d.hinge + np.array([0.0, 0.0, 0.2]),
                zoom=0.1,
            )
        elif macro in ("surface_scan", "follow_perimeter"):
            corners = scene.surface.corners
            prim = _place(s, rng, "plane", corners[[1, 0, 3]], scene.surface.center, zoom=0.4)
        else:  # place_device: a device in the closed gripper
            s.grip("close")
            edge = scene.package.front_bottom_edge
            prim = _place(s, rng, "line", edge, edge.mean(axis=0))
        options = {"angle_deg": 85.0} if macro == "move_around_axis" else None
        path = s.plan(macro, prim.primitive_id, options)
        if not path.ok:
            return {"ok": False, "why": f"refused: {path.reason}"}
        log = s.play(path.path_id, timeout=90.0)
    except Exception as exc:  # a benchmark counts failures; it does not stop on them
        return {"ok": False, "why": f"{type(exc).__name__}: {exc}"}
    v = s.judge.verdicts
    return {
        "ok": v.success(macro),
        "why": "; ".join(v.events),
        "time_s": log.t[-1],
        "grasp_mm": v.grasp_distance_m * 1e3,
        "grasp_deg": float(np.degrees(v.grasp_angle_rad)),
        "door_deg": float(np.degrees(v.door_max_rad)),
        "coverage": v.coverage,
        "perimeter_dev_mm": v.perimeter_max_dev_m * 1e3,
        "device_mm": v.device_error_m * 1e3,
    }


# -- the VCR ------------------------------------------------------------------------------------
SCRIPT = [
    (0.0, "play", {}),
    (2.5, "pause", {}),
    (3.2, "back", {}),
    (4.2, "pause", {}),
    (4.8, "play", {"speed": 0.3}),
    (6.0, "speed", {"speed": 1.0}),
]


def vcr_run(seed: int, stop_time: float) -> dict:
    s, rng = _session(seed)
    prim = _place(s, rng, "line", s.scene.pipe.ends, s.scene.pipe.center)
    path = s.plan("grab_pipe", prim.primitive_id)
    original = PathPlayer.__init__

    def with_stop_time(self, *args, **kwargs):  # the VCR under test, or the step baseline
        kwargs["stop_time_s"] = stop_time
        original(self, *args, **kwargs)

    PathPlayer.__init__ = with_stop_time
    try:
        log = s.play(path.path_id, SCRIPT, timeout=40.0)
    finally:
        PathPlayer.__init__ = original
    arr = log.arrays()
    t, s_dot, s_ddot = arr["t"], arr["s_dot"], arr["s_ddot"]
    dt = s.dt
    paused = np.flatnonzero((t > 2.5) & (np.abs(s_dot) < 1e-9))
    pause_time = float(t[paused[0]] - 2.5) if paused.size else float("nan")
    rate = path.checks["rate"]
    jerk_limit = 4.0 * rate / stop_time**2
    peak_jerk = float(np.max(np.abs(np.diff(s_ddot))) / dt)
    forward = arr["tool"][t < 3.2]
    backing = arr["tool"][(t > 3.2) & (t < 4.2)]
    retrace = np.linalg.norm(backing[:, None, :] - forward[None, ::2, :], axis=2).min(axis=1)
    qd = arr["qd"]
    qdd = np.abs(np.diff(qd, axis=0)) / dt
    windows = [(t > c) & (t < c + 0.5) for c, _, _ in SCRIPT[1:]]
    transition_acc = max(float(qdd[w[1:]].max()) for w in windows)
    guard = int(sum(bool(g) for g in arr["guard"]))
    tracking = np.array(arr["tool"])
    return {
        "pause_to_standstill_s": pause_time,
        "peak_path_jerk_over_limit": peak_jerk / jerk_limit,
        "retrace_max_mm": float(retrace.max() * 1e3),
        "peak_joint_accel_at_transitions": transition_acc,
        "max_joint_speed_jump_per_tick": float(np.abs(np.diff(qd, axis=0)).max()),
        "guard_zero_ticks": guard,
        "done": arr["mode"][-1] == "done",
        "samples": len(tracking),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--scenes", type=int, help="scenes per macro (default 100, quick 5)")
    parser.add_argument("--seed", type=int, default=2026)
    args = parser.parse_args()
    n = args.scenes or (5 if args.quick else 100)
    started = time.time()
    results: dict = {"scenes": n, "click_noise_px": CLICK_PX}

    results["targeting_error_mm"] = targeting(3 if args.quick else 20, args.seed)
    rows = []
    for dist, per in results["targeting_error_mm"].items():
        for key, st in per.items():
            rows.append([dist, key, st["n"], st["p50"], st["p95"], st["predicted_sigma_mm_p50"]])
    print(f"\nTargeting error against the truth (clicks {CLICK_PX} px)")
    print(table(rows, ["distance", "cameras", "n", "err mm p50", "p95", "predicted sigma p50"]))

    macro_results = {}
    rows = []
    for macro in MACROS:
        runs = [run_macro(macro, args.seed + i) for i in range(n)]
        ok = [r for r in runs if r["ok"]]
        fails = [r["why"] for r in runs if not r["ok"]][:5]
        macro_results[macro] = {
            "success_rate": len(ok) / n,
            "n": n,
            "failures": fails,
            "runs": runs,
        }
        times = [r["time_s"] for r in runs if "time_s" in r]
        rows.append(
            [
                macro,
                f"{len(ok)}/{n}",
                len(ok) / n,
                float(np.median(times)) if times else float("nan"),
            ]
        )
        print(f"{macro}: {len(ok)}/{n} ({time.time() - started:.0f} s)", flush=True)
    results["macros"] = macro_results
    print(f"\nSuccess per macro over {n} randomized scenes (goal >= 95 %)")
    print(table(rows, ["macro", "succeeded", "rate", "play time s p50"]))

    vcr = {"jerk-limited VCR (0.25 s stop)": [], "step VCR baseline (0.01 s stop)": []}
    for i in range(min(n, 3 if args.quick else 20)):
        vcr["jerk-limited VCR (0.25 s stop)"].append(vcr_run(args.seed + i, 0.25))
        vcr["step VCR baseline (0.01 s stop)"].append(vcr_run(args.seed + i, 0.01))
    rows = []
    summary = {}
    for key, runs in vcr.items():
        agg = {
            k: float(np.nanmax([r[k] for r in runs]))
            for k in (
                "pause_to_standstill_s",
                "peak_path_jerk_over_limit",
                "retrace_max_mm",
                "peak_joint_accel_at_transitions",
                "max_joint_speed_jump_per_tick",
                "guard_zero_ticks",
            )
        }
        agg["all_done"] = all(r["done"] for r in runs)
        summary[key] = agg
        rows.append(
            [
                key,
                agg["pause_to_standstill_s"],
                agg["peak_path_jerk_over_limit"],
                agg["retrace_max_mm"],
                agg["peak_joint_accel_at_transitions"],
                agg["max_joint_speed_jump_per_tick"],
                agg["all_done"],
            ]
        )
    results["vcr"] = {"worst_over_runs": summary, "runs": vcr}
    print(
        f"\nVCR over {len(vcr['jerk-limited VCR (0.25 s stop)'])} grabs: play, pause, back, "
        "pause, play 0.3x, speed 1x (worst over runs)"
    )
    print(
        table(
            rows,
            [
                "player",
                "pause s",
                "jerk/limit",
                "retrace mm",
                "joint acc rad/s2 at transitions",
                "max qd jump/tick",
                "done",
            ],
        )
    )
    results["wall_time_s"] = time.time() - started
    path = write_results("sketch", results, quick=args.quick)
    print(f"\nresults: {path}")


if __name__ == "__main__":
    main()
