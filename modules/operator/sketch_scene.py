"""Active Sketch in the station's 3-D panel: the snapshots' camera frusta, the placed primitives
and the path being played with the arm's progress along it, as JSON-ready dicts. Pure.

Everything goes to the page in the arm's base frame [m] (the 3-D panel's frame): an item given in
another frame (``frame`` of the message: the table, the world) is moved with the static
``T_base_frame`` the caller looks up; an item whose frame is not tied to the base is left out
rather than drawn in the wrong place. A matrix goes as 16 numbers, row by row.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from umbra.connectors.path_messages import ToolPath, VcrState
from umbra.connectors.sketch_messages import SketchPrimitive, StereoSnapshot

#: Snapshots and primitives kept for the panel (the oldest go first).
MAX_SNAPSHOTS = 4
MAX_PRIMITIVES = 40
#: Points of a path sent to the page (a longer path is thinned evenly, its ends kept).
MAX_PATH_POINTS = 200

#: T_base_frame for a frame name (None: not tied to the panel's base by static frames).
FrameLookup = Callable[[str], "np.ndarray | None"]


def _rows(T: np.ndarray) -> list[float]:
    return [round(float(x), 5) for x in np.asarray(T, dtype=float).reshape(16)]


def _points(T_base_frame: np.ndarray, points: np.ndarray) -> list[list[float]]:
    """``points`` (N x 3, m, in the item's frame) in the base frame, rounded to 0.1 mm."""
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    q = p @ T_base_frame[:3, :3].T + T_base_frame[:3, 3]
    return [[round(float(v), 4) for v in row] for row in q]


def _frustum(name: str, T: np.ndarray, K: np.ndarray, image: np.ndarray) -> dict[str, Any]:
    """A snapshot camera: its pose and its field of view from ``K`` [px] and the image's size."""
    height, width = np.asarray(image).shape[:2]
    fx = float(np.asarray(K)[0, 0])
    return {
        "name": name,
        "T": _rows(T),
        "tan_half_fov_x": round(width / (2.0 * fx), 5) if fx > 0 else 0.5,
        "aspect": round(width / height, 5) if height else 4 / 3,
    }


def snapshot_view(snap: StereoSnapshot, T_base_frame: np.ndarray) -> dict[str, Any]:
    """One stereo snapshot: both cameras where they were when it was taken."""
    return {
        "id": snap.snapshot_id,
        "cameras": [
            _frustum(
                snap.camera_a_name or "a",
                T_base_frame @ np.asarray(snap.T_base_camera_a),
                snap.K_a,
                snap.image_a,
            ),
            _frustum(
                snap.camera_b_name or "b",
                T_base_frame @ np.asarray(snap.T_base_camera_b),
                snap.K_b,
                snap.image_b,
            ),
        ],
    }


def primitive_view(prim: SketchPrimitive, T_base_frame: np.ndarray) -> dict[str, Any]:
    """A placed primitive: its triangulated vertices and the edges drawn between them."""
    edges = np.asarray(prim.edges, dtype=int).reshape(-1, 2)
    return {
        "id": prim.primitive_id,
        "kind": prim.kind,
        "points": _points(T_base_frame, prim.points),
        "edges": [[int(a), int(b)] for a, b in edges],
    }


def path_line(path: ToolPath, T_base_frame: np.ndarray) -> dict[str, Any] | None:
    """The path as drawn: its id, macro and the tool's positions along it (thinned to
    ``MAX_PATH_POINTS``). None: a path without tool poses (nothing to draw)."""
    positions = np.asarray(path.T_base_tool, dtype=float).reshape(-1, 4, 4)[:, :3, 3]
    if len(positions) == 0:
        return None
    keep = np.unique(np.linspace(0, len(positions) - 1, min(len(positions), MAX_PATH_POINTS)))
    return {
        "id": path.path_id,
        "macro": path.macro,
        "points": _points(T_base_frame, positions[keep.astype(int)]),
    }


def arm_on_path(path: ToolPath, T_base_frame: np.ndarray, vcr: VcrState | None) -> dict[str, Any]:
    """While the player holds ``path``: where the arm is on it (``at``, interpolated at the
    player's ``s``), its ``progress`` (0..1) and the player's ``mode``; else nothing (None, "")."""
    if vcr is None or vcr.path_id != path.path_id:
        return {"at": None, "progress": None, "mode": ""}
    positions = np.asarray(path.T_base_tool, dtype=float).reshape(-1, 4, 4)[:, :3, 3]
    s = np.asarray(path.s, dtype=float)
    at = (
        np.array([np.interp(vcr.s, s, positions[:, i]) for i in range(3)])
        if len(s) == len(positions)
        else positions[-1]
    )
    return {
        "at": _points(T_base_frame, at)[0],
        "progress": round(min(max(float(vcr.progress), 0.0), 1.0), 4),
        "mode": vcr.mode,
    }


def _keep_newest(items: dict[str, Any], key: str, item: Any, limit: int) -> None:
    """``item`` under ``key`` as the newest of ``items`` (replacing an older one of that key),
    the oldest dropped beyond ``limit``."""
    items.pop(key, None)
    items[key] = item
    while len(items) > limit:
        items.pop(next(iter(items)))


class SketchItems:
    """What Active Sketch has made so far, for the panel: the latest snapshots and primitives
    (by id, a newer one with the same id replaces the older), and the path last loaded.

    :meth:`view` places them in the base frame once per change (the static frames do not
    move); only the arm's place on the path is worked out at each call."""

    def __init__(self) -> None:
        self.snapshots: dict[str, StereoSnapshot] = {}
        self.primitives: dict[str, SketchPrimitive] = {}
        self.path: ToolPath | None = None
        self._placed: dict[str, Any] | None = None  #: the items placed, until the next change
        self._version = 0  #: changes so far (the page rebuilds its drawing when it changes)
        self._T_base_path: np.ndarray | None = None

    def add_snapshot(self, snap: StereoSnapshot) -> None:
        _keep_newest(self.snapshots, snap.snapshot_id, snap, MAX_SNAPSHOTS)
        self._changed()

    def add_primitive(self, prim: SketchPrimitive) -> None:
        _keep_newest(self.primitives, prim.primitive_id, prim, MAX_PRIMITIVES)
        self._changed()

    def set_path(self, path: ToolPath) -> None:
        self.path = path
        self._changed()

    def _changed(self) -> None:
        self._version += 1
        self._placed = None

    def __bool__(self) -> bool:
        return bool(self.snapshots or self.primitives or self.path is not None)

    def view(self, lookup: FrameLookup, vcr: VcrState | None) -> dict[str, Any]:
        """The panel's Active Sketch items in the base frame; items whose frame ``lookup``
        cannot tie to the base are counted in ``untied``, not drawn. ``lookup`` must give the
        same answers for the whole run (static frames)."""
        if self._placed is None:
            self._placed = self._place(lookup)
        out = dict(self._placed)
        line = out["path"]
        if line is not None and self.path is not None and self._T_base_path is not None:
            out["path"] = {**line, **arm_on_path(self.path, self._T_base_path, vcr)}
        return out

    def _place(self, lookup: FrameLookup) -> dict[str, Any]:
        untied = 0

        def placed(items: Any, view_of: Callable[[Any, np.ndarray], Any]) -> list[Any]:
            nonlocal untied
            drawn = []
            for item in items:
                T = lookup(item.frame)
                if T is None:
                    untied += 1
                else:
                    drawn.append(view_of(item, T))
            return drawn

        self._T_base_path = None if self.path is None else lookup(self.path.frame)
        lines = placed([] if self.path is None else [self.path], path_line)
        return {
            "snapshots": placed(self.snapshots.values(), snapshot_view),
            "primitives": placed(self.primitives.values(), primitive_view),
            "path": lines[0] if lines else None,
            "untied": untied,
            "version": self._version,
        }
