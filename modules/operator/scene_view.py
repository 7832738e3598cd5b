"""What the station's 3-D panel draws, from the graph's poses, as JSON-ready dicts. Pure.

Everything is in the arm's base frame [m]: the link frames (``T_base_link`` from the arm's
kinematics), the wrist camera (``T_table_camera`` from the world, moved into the base frame with
the static ``T_base_table``) with its frustum, and the tool's patch (``T_table_patch``). A
matrix goes to the page as 16 numbers, row by row.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from umbra.connectors.messages import Pose, Poses


def _rows(T: np.ndarray) -> list[float]:
    return [round(float(x), 5) for x in np.asarray(T, dtype=float).reshape(16)]


def scene_view(
    links: Poses | None,
    camera: Pose | None,
    patch: Pose | None,
    T_base_camera_parent: np.ndarray | None,
    T_base_patch_parent: np.ndarray | None,
    fov_deg: float,
    aspect: float,
    patch_size_m: tuple[float, float],
) -> dict[str, Any] | None:
    """The panel's scene (None: no link poses, so no arm to draw). ``camera`` and ``patch`` are
    poses in their parent frames (the world's table), drawn only when the static transform from
    the arm's base to that parent is known (``T_base_camera_parent``, ``T_base_patch_parent``);
    ``fov_deg`` is the camera's horizontal field of view, ``aspect`` its image's width/height."""
    if links is None:
        return None
    out: dict[str, Any] = {
        "frame": links.frame,
        "links": [
            {"name": name, "T": _rows(T)}
            for name, T in zip(links.children, np.asarray(links.matrices), strict=False)
        ],
        "camera": None,
        "patch": None,
    }
    if camera is not None and T_base_camera_parent is not None:
        out["camera"] = {
            "name": camera.child,
            "T": _rows(T_base_camera_parent @ np.asarray(camera.matrix)),
            "tan_half_fov_x": round(math.tan(math.radians(fov_deg) / 2.0), 5),
            "aspect": round(aspect, 5),
        }
    if patch is not None and T_base_patch_parent is not None:
        out["patch"] = {
            "name": patch.child,
            "T": _rows(T_base_patch_parent @ np.asarray(patch.matrix)),
            "size": [float(patch_size_m[0]), float(patch_size_m[1])],
        }
    return out
