"""What the 3-D view draws a camera with: the frustum sizes and colours, the video as the
page sends it, and a scene-tree name for an item."""

from __future__ import annotations

import cv2
import numpy as np

#: size of a live camera's frustum (viser's volume-normalized scale): the wrist camera's
#: is large enough for its video to be read in the overview (at 0.05 it was 70 px wide there)
#: and still in front of the gripper
FRUSTUM_SCALES = {"wrist": 0.12, "left": 0.15, "right": 0.15}
SNAPSHOT_SCALE = 0.2  #: size of a snapshot's frustum
CAMERA_COLORS = {"wrist": (230, 120, 20), "left": (20, 120, 230), "right": (20, 170, 90)}


def video_rgba(image_bgr: np.ndarray, opacity: float, max_width: int) -> np.ndarray:
    """The image as the page draws it: at most ``max_width`` wide, RGB, plus an alpha channel
    of ``opacity`` (0 transparent .. 1 opaque) when it is not opaque."""
    h, w = image_bgr.shape[:2]
    if w > max_width:
        image_bgr = cv2.resize(
            image_bgr, (max_width, max(1, round(h * max_width / w))), interpolation=cv2.INTER_AREA
        )
    if opacity >= 1.0:
        return cv2.cvtColor(image_bgr, cv2.COLOR_BGR2RGB)
    rgba = cv2.cvtColor(image_bgr, cv2.COLOR_BGR2RGBA)
    rgba[..., 3] = round(255 * max(0.0, opacity))
    return rgba


def node_name(item_id: str) -> str:
    """A scene-tree name for an item id (no slashes)."""
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in item_id) or "item"
