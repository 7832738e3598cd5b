"""What the /sketch page shows, as plain JSON built from the graph's messages (pure).

The page draws in image pixels (u right, v down) of the snapshot's images. It gets the
fundamental matrix ``F`` (``x_b^T F x_a = 0``, ideal pixels; the page's fallback until the
epipolar curve of a vertex, distortion included, comes from ``/sketch/epipolar``, computed by
:meth:`umbra.modules.sketch.stereo.StereoPair.epipolar_curve_b`), each image's size, the camera
matrices for the test tools, every primitive with its vertices reprojected from 3-D, its
centroid (m, base: where the cameras aim), largest sigma (mm) and warnings in words (a vertex
whose depth is poorly constrained, and what to do: ``modules/sketch/depth_check.py``), the macro
menu of each kind of primitive, and the planned tool path projected into both images, and the
last macro's verdict (success or miss, with the numbers), and each camera's pan/tilt unit and
zoom as their devices report them (:mod:`umbra.modules.sketch_page.camera_view`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from umbra.connectors.messages import Status
from umbra.connectors.path_messages import ToolPath, VcrState
from umbra.connectors.sketch_messages import Macro, SketchPrimitive, StereoSnapshot
from umbra.connectors.states import Outcome, Verdict
from umbra.modules.geometry.rays import fundamental_matrix
from umbra.modules.sketch.depth_check import depth_warnings
from umbra.modules.sketch.macros import MENU, macro_label, menu_for
from umbra.modules.sketch.stereo import StereoPair


def _r(values: Any, digits: int = 3) -> Any:
    return np.round(np.asarray(values, dtype=float), digits).tolist()


def _menu(items: list[tuple[Macro, str]]) -> list[list[str]]:
    """Menu entries as ``[macro, what it does, its label for a person]``."""
    return [[name, help_text, macro_label(name)] for name, help_text in items]


def page_state(
    snapshot: StereoSnapshot | None,
    primitives: list[SketchPrimitive],
    path: ToolPath | None,
    vcr: VcrState | None,
    status: Status | None,
    verdict: Verdict | None = None,
    cameras: list[dict[str, Any]] | None = None,
) -> dict[str, Any]:
    """The page's JSON state (see module docstring)."""
    state: dict[str, Any] = {
        "snapshot": None,
        "primitives": [],
        "menu": _menu(menu_for(None)),
        "menus": {kind: _menu(items) for kind, items in MENU.items()},
        "path": None,
        "vcr": None,
        "status": None,
        "verdict": None,
        "cameras": cameras or [],
    }
    pair = None
    if snapshot is not None:
        pair = StereoPair.from_snapshot(snapshot)
        state["snapshot"] = {
            "id": snapshot.snapshot_id,
            "width": int(snapshot.image_a.shape[1]),
            "height": int(snapshot.image_a.shape[0]),
            "size_a": [int(snapshot.image_a.shape[1]), int(snapshot.image_a.shape[0])],
            "size_b": [int(snapshot.image_b.shape[1]), int(snapshot.image_b.shape[0])],
            "zoom": [snapshot.zoom_a, snapshot.zoom_b],
            "F": _r(fundamental_matrix(pair.P_a, pair.P_b), 12),
            "P_a": _r(pair.P_a, 9),
            "P_b": _r(pair.P_b, 9),
        }
    current = [p for p in primitives if snapshot is None or p.snapshot_id == snapshot.snapshot_id]
    for prim in current:
        entry = {
            "id": prim.primitive_id,
            "kind": prim.kind,
            "pixels_a": _r(prim.pixels_a),
            "pixels_b": _r(prim.pixels_b),
            "edges": np.asarray(prim.edges).tolist(),
            "points_m": _r(prim.points, 5),
            "centroid_m": _r(np.mean(prim.points, axis=0), 5),
            "sigma_mm": _r(np.sqrt(np.linalg.eigvalsh(prim.covariances)[:, -1]) * 1e3, 2),
            "warnings": [],
        }
        if pair is not None:
            entry["reprojected_a"] = _r(pair.project("a", prim.points))
            entry["reprojected_b"] = _r(pair.project("b", prim.points))
            entry["warnings"] = depth_warnings(pair, prim)
        state["primitives"].append(entry)
    if current:
        state["menu"] = _menu(menu_for(current[-1]))
    if path is not None:
        entry = {
            "id": path.path_id,
            "macro": path.macro,
            "label": macro_label(path.macro),
            "ok": bool(path.ok),
            "reason": path.reason,
            "duration_s": float(path.checks.get("duration", 0.0)),
        }
        if pair is not None and len(path.T_base_tool):
            points = np.asarray(path.T_base_tool)[:, :3, 3]
            entry["preview_a"] = _r(pair.project("a", points), 1)
            entry["preview_b"] = _r(pair.project("b", points), 1)
            s_end = float(path.s[-1]) if len(path.s) and path.s[-1] > 0 else 1.0
            entry["preview_s"] = _r(np.asarray(path.s, dtype=float) / s_end, 4)
        state["path"] = entry
    if vcr is not None:
        state["vcr"] = {
            "path": vcr.path_id,
            "mode": vcr.mode,
            "s": vcr.s,
            "progress": vcr.progress,
            "speed": vcr.speed,
            "reason": vcr.reason,
        }
    if status is not None:
        state["status"] = {"stage": status.stage, "message": status.message}
    if verdict is not None:
        state["verdict"] = {
            "macro": verdict.stage,
            "label": macro_label(verdict.stage),
            "text": verdict.message,
            "outcome": str(verdict.outcome),
            "success": verdict.outcome == Outcome.SUCCEEDED,
        }
    return state
