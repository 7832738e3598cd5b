"""``umbra sketch ...``: Active Sketch from the command line, on the simulated cell.

A session lives in a folder: ``session.json`` holds its seed and the commands given so far; each
call replays them (the simulation is deterministic) and then runs the new one, so separate
calls act on one session. Snapshots are written as PNG images with a JSON of both camera models.

    umbra sketch new S --seed 3                    a randomized scene, cameras wide
    umbra sketch aim S --at pipe_center --zoom 0.3   (or: aim S X Y Z)
    umbra sketch snapshot S                        -> S/snap1_a.png, S/snap1_b.png, S/snap1.json
    umbra sketch place S line --a 525,109 107,175 --b 544,109 101,171
    umbra sketch place S line --truth pipe --noise 0.5   (simulated clicks on the true pipe)
                                  (its ``warnings`` name a vertex whose depth is poorly
                                  constrained and what to do: modules/sketch/depth_check.py)
    umbra sketch macros S line1
    umbra sketch plan S grab_pipe line1           (a triad: plan S make_box triad1)
    umbra sketch play S path1 --script "0:play 2:pause 2.5:back 3.5:play@0.5 5:speed@1"
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np

from umbra.connectors.cli_support import print_json
from umbra.connectors.errors import UserError
from umbra.connectors.sketch_messages import Macro
from umbra.modules.sketch.depth_check import depth_warnings
from umbra.modules.sketch.macros import MacroError, check_options, macro_named
from umbra.modules.sketch.primitives import KINDS, PrimitiveError
from umbra.modules.sketch.session import SessionError, SketchSession
from umbra.modules.sketch.session_file import load_session_state
from umbra.modules.sketch.stereo import StereoPair
from umbra.modules.trajectory.vcr import ACTIONS as VCR_ACTIONS
from umbra.modules.trajectory.vcr import VcrError
from umbra.modules.world.scene_objects import targets_from_objects

NAME = "sketch"
HELP = "Active Sketch on the simulated cell: snapshot, place primitives, macros, plan, play"
GUIDE = "docs/guide/active-sketch.md"  # the guide page this command's --help points to
STATE = "session.json"


def configure(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="action", required=True, metavar="ACTION")
    new = sub.add_parser("new", help="start a session in a folder")
    new.add_argument("session", type=Path)
    new.add_argument("--seed", type=int, default=0, help="scene randomization seed")
    aim = sub.add_parser("aim", help="slew both PTUs to watch a point (and zoom)")
    aim.add_argument("session", type=Path)
    aim.add_argument("xyz", nargs="*", type=float, help="X Y Z in metres, base frame")
    aim.add_argument("--at", help="a true scene feature instead (pipe_center, handle_center...)")
    aim.add_argument("--zoom", type=float, help="zoom 0 (wide) .. 1 (tele)")
    snap = sub.add_parser("snapshot", help="take a stereo snapshot (PNG + JSON)")
    snap.add_argument("session", type=Path)
    place = sub.add_parser("place", help="place a primitive by its pixels in both images")
    place.add_argument("session", type=Path)
    place.add_argument("kind", choices=list(KINDS))
    place.add_argument("--a", nargs="+", default=[], metavar="U,V", help="vertices in image a")
    place.add_argument("--b", nargs="+", default=[], metavar="U,V", help="vertices in image b")
    place.add_argument("--truth", help="click a true feature instead (pipe, handle, hinge...)")
    place.add_argument("--noise", type=float, default=0.5, help="click noise with --truth [px]")
    macros = sub.add_parser("macros", help="the macros a primitive (or nothing) offers")
    macros.add_argument("session", type=Path)
    macros.add_argument("primitive", nargs="?")
    plan = sub.add_parser("plan", help="plan and check a macro")
    plan.add_argument("session", type=Path)
    plan.add_argument("macro")
    plan.add_argument("primitive", nargs="?")
    plan.add_argument("--option", action="append", default=[], metavar="KEY=VALUE")
    play = sub.add_parser("play", help="play a checked path with a VCR script")
    play.add_argument("session", type=Path)
    play.add_argument("path")
    play.add_argument(
        "--script",
        default="0:play",
        help="T:ACTION[@SPEED|@S] steps, e.g. '0:play 2:pause 2.5:back 4:play@0.5 6:seek@0.3'",
    )
    play.add_argument("--timeout", type=float, default=60.0, help="seconds of simulated time")
    for p in (new, aim, snap, place, macros, plan, play):
        p.add_argument("--json", action="store_true", help="print one JSON object")


def main(args: argparse.Namespace) -> int:
    folder: Path = args.session
    if args.action == "new":
        if args.seed < 0:
            raise UserError(f"sketch new: expected a seed >= 0, got {args.seed}")
        folder.mkdir(parents=True, exist_ok=True)
        _save(folder, {"seed": args.seed, "events": []})
        session = SketchSession(seed=args.seed)
        result: dict[str, Any] = {"session": str(folder), "seed": args.seed}
    else:
        state = _load(folder)
        session = SketchSession(seed=state["seed"])
        for number, event in enumerate(state["events"], start=1):
            try:
                _apply(session, folder, event, replay=True)
            except UserError as exc:  # a hand-edited event the session cannot replay
                raise UserError(
                    f"{folder / STATE}: error: event {number} ({event['cmd']}) cannot be "
                    f"replayed: {exc}"
                ) from None
        event = _event(args)
        result = _apply(session, folder, event, replay=False)
        state["events"].append(event)
        _save(folder, state)
    if args.json:
        print_json(result)
    else:
        for key, value in result.items():
            print(f"{key}: {value}")
    return 0


def _event(args: argparse.Namespace) -> dict[str, Any]:
    a = args.action
    if a == "aim":
        if (args.at is None) == (len(args.xyz) != 3):
            raise UserError("aim: expected X Y Z or --at FEATURE (one of them)")
        if not all(np.isfinite(args.xyz)):
            raise UserError(f"aim: expected finite X Y Z in metres, got {args.xyz}")
        if args.zoom is not None and not (np.isfinite(args.zoom) and 0.0 <= args.zoom <= 1.0):
            raise UserError(f"aim: expected --zoom within 0 .. 1, got {args.zoom}")
        return {"cmd": a, "xyz": args.xyz, "at": args.at, "zoom": args.zoom}
    if a == "snapshot":
        return {"cmd": a}
    if a == "place":
        if args.truth is None and not (args.a and args.b):
            raise UserError("place: expected --a U,V ... and --b U,V ..., or --truth FEATURE")
        if not (np.isfinite(args.noise) and 0.0 <= args.noise <= 20.0):
            raise UserError(f"place: expected --noise within 0 .. 20 px, got {args.noise}")
        if args.truth is None:
            _pixels(args.a), _pixels(args.b)  # refuse bad pixels before the event is kept
        return {
            "cmd": a,
            "kind": args.kind,
            "a": args.a,
            "b": args.b,
            "truth": args.truth,
            "noise": args.noise,
            "seed": len(_load(args.session)["events"]),
        }
    if a == "macros":
        return {"cmd": a, "primitive": args.primitive}
    if a == "plan":
        options = {}
        for item in args.option:
            key, sep, value = item.partition("=")
            try:
                options[key] = float(value)
            except ValueError:
                raise UserError(f"plan --option: expected KEY=NUMBER, got {item!r}") from None
            if not sep or not np.isfinite(options[key]):
                raise UserError(f"plan --option: expected KEY=NUMBER (finite), got {item!r}")
        try:
            macro = macro_named(args.macro)
        except MacroError as exc:
            raise UserError(f"plan: {exc}") from None
        try:
            check_options(macro, options)
        except MacroError as exc:
            raise UserError(f"plan --option: {exc}") from None
        return {"cmd": a, "macro": str(macro), "primitive": args.primitive, "options": options}
    if not (np.isfinite(args.timeout) and 0 < args.timeout <= 3600):
        raise UserError(f"play: expected --timeout within 0 .. 3600 s, got {args.timeout}")
    return {"cmd": a, "path": args.path, "script": _script(args.script), "timeout": args.timeout}


def _script(text: str) -> list[list[Any]]:
    steps = []
    for word in text.split():
        when, sep, what = word.partition(":")
        action, _, value = what.partition("@")
        try:
            t = float(when)
            number = float(value) if value else None
        except ValueError:
            raise UserError(f"play --script: expected T:ACTION[@NUMBER], got {word!r}") from None
        if not sep or not action:
            raise UserError(f"play --script: expected T:ACTION[@NUMBER], got {word!r}")
        if not (np.isfinite(t) and t >= 0) or (number is not None and not np.isfinite(number)):
            raise UserError(
                f"play --script: expected a time >= 0 s and a finite number, got {word!r}"
            )
        if action not in VCR_ACTIONS:
            raise UserError(
                f"play --script: unknown action {action!r} in {word!r}; expected one of "
                f"{', '.join(VCR_ACTIONS)}"
            )
        steps.append([t, action, number])
    return steps


def _apply(session: SketchSession, folder: Path, e: dict, replay: bool) -> dict[str, Any]:
    try:
        return _run(session, folder, e, replay)
    except (SessionError, MacroError, PrimitiveError, VcrError) as exc:
        raise UserError(f"sketch {e['cmd']}: {exc}") from None
    except ValueError as exc:  # a degenerate primitive or pose: the planner says why
        raise UserError(f"sketch {e['cmd']}: {exc}") from None


def _run(session: SketchSession, folder: Path, e: dict, replay: bool) -> dict[str, Any]:
    import cv2

    cmd = e["cmd"]
    if cmd == "aim":
        if e["at"]:
            point = _feature(session, e["at"], "aim --at")
            if point.ndim != 1:
                raise SessionError(f"aim --at: {e['at']!r} is not a point; try {e['at']}_center")
        else:
            point = np.asarray(e["xyz"], dtype=float)
        session.aim(point, e["zoom"])
        return {"aimed_at_m": np.round(point, 4).tolist(), "zoom": session.zooms}
    if cmd == "snapshot":
        snap = session.snapshot(render=not replay)
        if not replay:
            sid = snap.snapshot_id
            cv2.imwrite(str(folder / f"{sid}_a.png"), snap.image_a)
            cv2.imwrite(str(folder / f"{sid}_b.png"), snap.image_b)
            models = {
                side: {
                    "K": getattr(snap, f"K_{side}").tolist(),
                    "dist": getattr(snap, f"dist_{side}").tolist(),
                    "zoom": getattr(snap, f"zoom_{side}"),
                    "T_base_camera": getattr(snap, f"T_base_camera_{side}").tolist(),
                }
                for side in ("a", "b")
            }
            (folder / f"{sid}.json").write_text(json.dumps(models, indent=1))
        return {
            "snapshot": snap.snapshot_id,
            "images": [f"{snap.snapshot_id}_a.png", f"{snap.snapshot_id}_b.png"],
        }
    if cmd == "place":
        if e["truth"]:
            points = _feature(session, e["truth"], "place --truth")
            if points.ndim == 1:
                points = points[None, :]
            rng = np.random.default_rng(e["seed"])
            a, b = session.true_pixels(points)
            a = a + rng.normal(0.0, e["noise"], a.shape)
            pair = StereoPair.from_snapshot(session.snapshots[list(session.snapshots)[-1]])
            along = pair.epipolar_line_b(a)[..., :2] @ np.array([[0.0, 1.0], [-1.0, 0.0]])
            b = b + rng.normal(0.0, e["noise"], (len(points), 1)) * along
        else:
            a, b = _pixels(e["a"]), _pixels(e["b"])
        prim = session.place(e["kind"], a, b)
        sigmas = np.sqrt(np.linalg.eigvalsh(prim.covariances)[:, -1])
        pair = StereoPair.from_snapshot(session.snapshots[prim.snapshot_id])
        return {
            "primitive": prim.primitive_id,
            "points_m": np.round(prim.points, 5).tolist(),
            "largest_sigma_mm": np.round(sigmas * 1e3, 3).tolist(),
            "pixels_b_on_epipolar_lines": np.round(prim.pixels_b, 3).tolist(),
            "macros": [m for m, _ in session.macros(prim.primitive_id)],
            "warnings": depth_warnings(pair, prim),
        }
    if cmd == "macros":
        return {"macros": dict(session.macros(e["primitive"]))}
    if cmd == "plan" and e["macro"] == Macro.MAKE_BOX:
        if not e["primitive"]:
            raise SessionError("make_box: expected a triad's id")
        box = session.make_box(e["primitive"])
        return {
            "box": box.box_id,
            "center_m": np.round(box.T_base_box[:3, 3], 4).tolist(),
            "size_m": np.round(box.size, 4).tolist(),
        }
    if cmd == "plan":
        path = session.plan(e["macro"], e["primitive"], e["options"])
        return {
            "path": path.path_id,
            "ok": path.ok,
            "reason": path.reason,
            "checks": {k: round(v, 5) for k, v in path.checks.items()},
        }
    script = [(t, action, _kwargs(action, number)) for t, action, number in e["script"]]
    log = session.play(e["path"], script, timeout=e["timeout"])
    v = session.judge.verdicts
    return {
        "mode": log.mode[-1] if log.mode else "",
        "duration_s": round(log.t[-1], 3) if log.t else 0.0,
        "macro": session.paths[e["path"]].macro,
        "success": v.success(session.paths[e["path"]].macro),
        "events": v.events,
        "door_angle_deg": round(float(np.degrees(session.scene.door.angle)), 2),
    }


def _feature(session: SketchSession, name: str, where: str) -> np.ndarray:
    """A true scene feature by name (simulated clicks and aims)."""
    features = targets_from_objects(session.scene.message())
    if name not in features:
        raise SessionError(f"{where}: unknown feature {name!r}; expected one of {sorted(features)}")
    return features[name]


def _kwargs(action: str, number: float | None) -> dict[str, float]:
    if number is None:
        return {}
    return {"s": number} if action == "seek" else {"speed": number}


def _pixels(words: list[str]) -> np.ndarray:
    out = []
    for w in words:
        parts = w.split(",")
        try:
            out.append([float(parts[0]), float(parts[1])])
        except (ValueError, IndexError):
            raise UserError(f"place: expected pixels as U,V, got {w!r}") from None
        if len(parts) != 2 or not np.all(np.isfinite(out[-1])):
            raise UserError(f"place: expected pixels as U,V (finite numbers), got {w!r}")
    return np.asarray(out)


def _load(folder: Path) -> dict[str, Any]:
    path = folder / STATE
    if not path.is_file():
        raise UserError(
            f"sketch: expected a session folder with {STATE}, found none at {folder} "
            "(start one with `umbra sketch new FOLDER`)"
        )
    return load_session_state(path)


def _save(folder: Path, state: dict[str, Any]) -> None:
    (folder / STATE).write_text(json.dumps(state, indent=1))
