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

from umbra.modules.sketch.messages import SketchPrimitive, StereoSnapshot, ToolPath, VcrState

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


def path_view(
    path: ToolPath, T_base_frame: np.ndarray, vcr: VcrState | None
) -> dict[str, Any] | None:
    """The path being played: the tool's positions along it and, while the player holds this
    path, where the arm is on it (``at``, interpolated at the player's ``s``), its ``progress``
    (0..1) and the player's ``mode``. None: a path without tool poses (nothing to draw)."""
    poses = np.asarray(path.T_base_tool, dtype=float).reshape(-1, 4, 4)
    if len(poses) == 0:
        return None
    positions = poses[:, :3, 3]
    keep = np.unique(np.linspace(0, len(positions) - 1, min(len(positions), MAX_PATH_POINTS)))
    out: dict[str, Any] = {
        "id": path.path_id,
        "macro": path.macro,
        "points": _points(T_base_frame, positions[keep.astype(int)]),
        "at": None,
        "progress": None,
        "mode": "",
    }
    if vcr is not None and vcr.path_id == path.path_id:
        s = np.asarray(path.s, dtype=float)
        at = (
            [float(np.interp(vcr.s, s, positions[:, i])) for i in range(3)]
            if len(s) == len(positions)
            else positions[-1].tolist()
        )
        out["at"] = _points(T_base_frame, np.asarray(at))[0]
        out["progress"] = round(min(max(float(vcr.progress), 0.0), 1.0), 4)
        out["mode"] = vcr.mode
    return out


class SketchItems:
    """What Active Sketch has made so far, for the panel: the latest snapshots and primitives
    (by id, a newer one with the same id replaces the older), and the path last loaded."""

    def __init__(self) -> None:
        self.snapshots: dict[str, StereoSnapshot] = {}
        self.primitives: dict[str, SketchPrimitive] = {}
        self.path: ToolPath | None = None

    def add_snapshot(self, snap: StereoSnapshot) -> None:
        self.snapshots.pop(snap.snapshot_id, None)
        self.snapshots[snap.snapshot_id] = snap
        while len(self.snapshots) > MAX_SNAPSHOTS:
            self.snapshots.pop(next(iter(self.snapshots)))

    def add_primitive(self, prim: SketchPrimitive) -> None:
        self.primitives.pop(prim.primitive_id, None)
        self.primitives[prim.primitive_id] = prim
        while len(self.primitives) > MAX_PRIMITIVES:
            self.primitives.pop(next(iter(self.primitives)))

    def __bool__(self) -> bool:
        return bool(self.snapshots or self.primitives or self.path is not None)

    def view(self, lookup: FrameLookup, vcr: VcrState | None) -> dict[str, Any]:
        """The panel's Active Sketch items in the base frame; items whose frame ``lookup``
        cannot tie to the base are counted in ``untied``, not drawn."""
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

        paths = placed([] if self.path is None else [self.path], lambda p, T: path_view(p, T, vcr))
        return {
            "snapshots": placed(self.snapshots.values(), snapshot_view),
            "primitives": placed(self.primitives.values(), primitive_view),
            "path": paths[0] if paths else None,
            "untied": untied,
        }
