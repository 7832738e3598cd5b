"""The jog pad's buttons in the world's words. Pure.

The camera frame is the live image's: x to the right, y down the image, z along the view, into
the scene. A jog along an axis of the chosen frame (tool or camera) is named by where it takes
the camera as seen in the live image: right / left, up / down the image, toward the scene
(down onto the tray for the wrist camera) / away (lifting). In the shipped pick-up the tool
frame is the camera's moved along z, so tool z+ goes toward the tray and tool z- lifts.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from umbra.modules.operator.jog import JogFrame

#: camera axis -> (name of +, name of -), as the operator sees it in the live image
_IMAGE_WORDS = (
    ("→ right", "← left"),
    ("↓ down the image", "↑ up the image"),
    ("toward (down)", "away (lift)"),
)
_ROLL_WORDS = ("↻ turn clockwise", "↺ turn anticlockwise")


def jog_labels(
    jog_frame: str, T_tool_camera: NDArray[np.float64] | None
) -> list[dict[str, object]]:
    """One entry per button: ``axis`` (0..3: x, y, z, roll of ``jog_frame``), ``sign`` (±1),
    ``label`` (world words) and ``axis_name`` (e.g. "tool z-"). ``T_tool_camera`` (the camera's
    pose in the tool frame) names tool-frame jogs; None: tool-frame jogs are not offered."""
    if jog_frame == JogFrame.CAMERA:
        R_camera_frame = np.eye(3)
    elif jog_frame == JogFrame.TOOL and T_tool_camera is not None:
        R_camera_frame = np.asarray(T_tool_camera, dtype=float)[:3, :3].T  # tool axes in camera
    else:
        return []
    out: list[dict[str, object]] = []
    for axis in range(4):
        for sign in (1, -1):
            if axis < 3:
                direction = sign * R_camera_frame[:, axis]
                k = int(np.argmax(np.abs(direction)))
                label = _IMAGE_WORDS[k][0 if direction[k] > 0 else 1]
            else:
                turn = sign * R_camera_frame[2, 2]  # roll about z, seen along the camera's view
                label = _ROLL_WORDS[0 if turn > 0 else 1]
            name = "xyz"[axis] if axis < 3 else "roll"
            out.append(
                {
                    "axis": axis,
                    "sign": sign,
                    "label": label,
                    "axis_name": f"{jog_frame} {name}{'+' if sign > 0 else '-'}",
                }
            )
    return out
