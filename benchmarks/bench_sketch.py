"""Active Sketch over randomized, seeded scenes: targeting error at 1-3 m with the operator's
clicks simulated with pixel noise (fixed wide cameras, the same-run baseline, against cameras
aimed by the PTUs and zoomed), success per macro with a simulated person dragging the handles
(:class:`Person`), without and with the depth warnings heeded, and the VCR's pause, jerk,
retrace and transition figures against a step-velocity VCR (the same-run baseline: no ramps).

    python benchmarks/bench_sketch.py [--quick] [--scenes N] [--seed S]

Snapshots are taken without rendering (the handles come from the true features projected through
the snapshot's camera models, plus the person's errors); rendering is measured by the tests.

A primitive with a warning (``modules/sketch/depth_check.py``), re-placed from another pan: placed
again on a snapshot from another pan (the cameras aimed 0.15 m beside it); still flagged, it is
refused (not played). This row measures advice the warning does not give: a pan turns each
camera about its own centre and leaves the epipolar lines where they were. Heeded by features:
its vertices are put on features that cross the epipolar lines (the pipe's visible ends) and
played; vertices already at features (corners, ends) are played as placed. Not heeded: every
primitive is played as placed.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.common import percentiles, table, write_results
from umbra.connectors.sketch_messages import Macro
from umbra.modules.sketch.depth_check import depth_warnings
from umbra.modules.sketch.primitives import KINDS
from umbra.modules.sketch.rig import default_rig
from umbra.modules.sketch.session import SketchSession
from umbra.modules.sketch.stereo import StereoNoise, StereoPair
from umbra.modules.trajectory.player import PathPlayer
from umbra.modules.world.scene_objects import SketchScene

CLICK_PX = 0.5
MACROS = (
    Macro.GRAB_PIPE,
    Macro.MOVE_AROUND_AXIS,
    Macro.SURFACE_SCAN,
    Macro.FOLLOW_PERIMETER,
    Macro.PLACE_DEVICE,
)


class Person:
    """An operator dragging a primitive's handles by eye.

    Image a: each handle lands within ``ACROSS_PX`` (1 sigma, each axis) of the point meant.
    Image b: the handle rides the epipolar line of its image-a mate (the page's constraint); the
    person leaves it at the spot of that line that agrees best with where they believe the
    point is (Mahalanobis-nearest, ``StereoPair.constrain_b`` with the belief's spread). The
    belief is off by ``ACROSS_PX`` across the edge the vertex sits on, and along it by
    ``ACROSS_PX`` at a feature (a corner, a visible end: the door, the handle bar, the surface,
    the package) or by ``ALONG_FRACTION`` of the edge's visible length on a featureless stretch
    (the pipe, marked between 25 % and 75 % of its length).

    Why these sizes: across a visible edge a dragged handle is put within about a pixel (twice
    the click noise the Sketch module declares by default, 0.5 px: a handle dragged onto an
    edge, not a click on a mark). Along a featureless edge nothing in the image tells one point
    from the next (the aperture problem: along an edge there is no local cue, Marr, *Vision*,
    1982), so "the same point" in both views is judged by proportion between the visible ends,
    as in bisecting a line by eye, which normal subjects do with errors of a few per cent of its
    length (Manning, Halligan & Marshall, Neuropsychologia 28, 1990); 5 % of the nominal pipe's
    435 px in image b is 22 px. Issue #41's two lines placed by eye on that pipe missed by 95 and
    17.2 mm at 2.2 mm per px along the epipolar lines: 43 and 8 px along it, the same size.
    """

    ACROSS_PX = 1.0
    ALONG_FRACTION = 0.05

    @staticmethod
    def place(
        session: SketchSession,
        rng: np.random.Generator,
        kind: str,
        points: np.ndarray,
        featureless_px: float = 0.0,
    ):
        """Drag ``kind``'s handles onto the true ``points`` (m, base) in the latest snapshot;
        ``featureless_px``: the visible length (px, image b) of the featureless edge they sit
        on (0: at features). Returns the placed primitive."""
        across = Person.ACROSS_PX
        true_a, true_b = session.true_pixels(points)
        a = true_a + rng.normal(0.0, across, true_a.shape)
        along = max(across, Person.ALONG_FRACTION * featureless_px)
        spreads = []
        for i in range(len(points)):
            edges = [e for e in KINDS[kind][1] if i in e]
            if len(edges) != 1:  # a point or a corner: a feature
                spreads.append(across**2 * np.eye(2))
                continue
            t = true_b[edges[0][1]] - true_b[edges[0][0]]
            t = t / np.linalg.norm(t)
            n = np.array([-t[1], t[0]])
            spreads.append(across**2 * np.outer(n, n) + along**2 * np.outer(t, t))
        belief = np.stack(
            [rng.multivariate_normal(m, S) for m, S in zip(true_b, spreads, strict=True)]
        )
        pair = StereoPair.from_snapshot(session.snapshots[list(session.snapshots)[-1]])
        b = pair.constrain_b(a, belief, np.stack(spreads))
        return session.place(kind, a, b)


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
    noise = StereoNoise(pixel_px=Person.ACROSS_PX)  # the declared handle error: its default
    return SketchSession(scene, seed=seed, noise=noise), np.random.default_rng(seed + 1)


def _place(session, rng, kind, points, aim_at, zoom=0.3):
    session.aim(aim_at, zoom=zoom)
    session.snapshot(render=False)
    a, b = _clicks(session, points, rng)
    return session.place(kind, a, b)


class Refused(Exception):
    """A flagged primitive the heeding operator would not play."""


def _warnings(session: SketchSession, prim) -> list[str]:
    return depth_warnings(StereoPair.from_snapshot(session.snapshots[prim.snapshot_id]), prim)


def _by_person(s, rng, kind, points, aim_at, zoom=0.3, featureless=None, heed=""):
    """The person places ``kind`` on ``points`` from a snapshot aimed at ``aim_at``;
    ``featureless``: the 3-D ends of the featureless edge the vertices sit on (None: at
    features). A flagged primitive, ``heed`` "pan": placed again from another pan, then
    refused; "features": placed again on the featureless edge's ends (features)."""
    if heed == "features":
        prim, warned = _by_person(s, rng, kind, points, aim_at, zoom, featureless)
        if warned and featureless is not None:
            return _by_person(s, rng, kind, featureless, aim_at, zoom)
        return prim, warned
    aims = [aim_at, aim_at + np.array([0.0, 0.15, 0.0])] if heed == "pan" else [aim_at]
    for at in aims:
        s.aim(at, zoom=zoom)
        s.snapshot(render=False)
        length = 0.0
        if featureless is not None:
            ends_b = s.true_pixels(featureless)[1]
            length = float(np.linalg.norm(ends_b[1] - ends_b[0]))
        prim = Person.place(s, rng, kind, points, length)
        warned = _warnings(s, prim)
        if not (heed and warned):
            return prim, warned
    raise Refused(warned[0])


def run_macro(macro: Macro, seed: int, heed: str = "") -> dict:
    s, rng = _session(seed)
    scene = s.scene
    warned: list[str] = []
    try:
        if macro == Macro.GRAB_PIPE:
            ends = scene.pipe.ends
            marks = ends[0] + np.outer([0.25, 0.75], ends[1] - ends[0])
            prim, warned = _by_person(
                s, rng, "line", marks, scene.pipe.center, featureless=ends, heed=heed
            )
        elif macro == Macro.MOVE_AROUND_AXIS:
            d = scene.door
            ends = np.stack(
                [d.handle_center - 0.05 * d.handle_axis, d.handle_center + 0.05 * d.handle_axis]
            )
            handle, warned = _by_person(s, rng, "line", ends, d.handle_center, heed=heed)
            grab = s.plan("grab_pipe", handle.primitive_id)
            if not grab.ok:
                return {"ok": False, "why": f"handle grab refused: {grab.reason}"}
            s.play(grab.path_id)
            prim, more = _by_person(
                s,
                rng,
                "line",
                np.stack([d.hinge_top, d.hinge]),
                d.hinge + np.array([0.0, 0.0, 0.2]),
                zoom=0.1,
                heed=heed,
            )
            warned = warned + more
        elif macro in (Macro.SURFACE_SCAN, Macro.FOLLOW_PERIMETER):
            corners = scene.surface.corners
            prim, warned = _by_person(
                s, rng, "plane", corners[[1, 0, 3]], scene.surface.center, zoom=0.4, heed=heed
            )
        else:  # place_device: a device in the closed gripper
            s.grip("close")
            edge = scene.package.front_bottom_edge
            prim, warned = _by_person(s, rng, "line", edge, edge.mean(axis=0), heed=heed)
        options = {"angle_deg": 85.0} if macro == Macro.MOVE_AROUND_AXIS else None
        path = s.plan(macro, prim.primitive_id, options)
        if not path.ok:
            return {"ok": False, "warned": bool(warned), "why": f"refused: {path.reason}"}
        log = s.play(path.path_id, timeout=90.0)
    except Refused as exc:
        return {"ok": False, "refused": True, "warned": True, "why": str(exc)}
    except Exception as exc:  # a benchmark counts failures; it does not stop on them
        return {"ok": False, "warned": bool(warned), "why": f"{type(exc).__name__}: {exc}"}
    v = s.judge.verdicts
    return {
        "ok": v.success(macro),
        "warned": bool(warned),
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
        warned = [r for r in runs if r.get("warned")]
        entry: dict = {
            "success_rate": sum(r["ok"] for r in runs) / n,
            "n": n,
            "warned": len(warned),
            "misses_warned": sum(not r["ok"] for r in warned),
            "misses_not_warned": sum(not r["ok"] and not r.get("warned") for r in runs),
            "failures": [r["why"] for r in runs if not r["ok"]][:5],
            "runs": runs,
        }
        row = [macro, f"{sum(r['ok'] for r in runs)}/{n}", len(warned), entry["misses_warned"]]
        row.append(entry["misses_not_warned"])
        for heed in ("pan", "features"):
            heeded = [run_macro(macro, args.seed + i, heed=heed) for i in range(n)]
            entry[f"heeded_by_{heed}"] = {
                "success_rate": sum(r["ok"] for r in heeded) / n,
                "refused": sum(bool(r.get("refused")) for r in heeded),
                "misses_played": sum(not r["ok"] and not r.get("refused") for r in heeded),
                "failures": [r["why"] for r in heeded if not r["ok"]][:5],
                "runs": heeded,
            }
            h = entry[f"heeded_by_{heed}"]
            row += [f"{sum(r['ok'] for r in heeded)}/{n}", h["refused"], h["misses_played"]]
        macro_results[macro] = entry
        print(f"{macro}: {row[1]} ({time.time() - started:.0f} s)", flush=True)
        rows.append(row)
    results["macros"] = macro_results
    results["person"] = {
        "across_px": Person.ACROSS_PX,
        "along_fraction_of_featureless_edge": Person.ALONG_FRACTION,
        "declared_noise": {"pixel_px": Person.ACROSS_PX, "handle_px": StereoNoise().handle_px},
    }
    print(
        f"\nSuccess per macro over {n} randomized scenes, a person dragging the handles "
        f"({Person.ACROSS_PX} px across an edge, {Person.ALONG_FRACTION:.0%} of a featureless "
        "edge along it). Re-placed from another pan (not advised): a flagged primitive placed "
        "again, else refused; by features: re-placed on features across the epipolar lines"
    )
    head = ["macro", "succeeded", "warned", "missed warned", "missed unwarned"]
    for heed in ("pan", "features"):
        head += [f"by {heed}: succeeded", "refused", "missed"]
    print(table(rows, head))

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
