"""The arm as the simulated cameras see it: its boxes (:mod:`umbra.modules.arm.arm_solids`) as the
faces a camera sees, back to front.

For the wrist camera's renderer (:class:`~umbra.modules.vision.scene.SceneRenderer`) the faces are
world :class:`~umbra.modules.vision.scene.Occluder` s, drawn in front of the table, the tool and the
patch (the arm is above them), shaded by how squarely they face the camera; the renderer clips
what lies behind the camera. For the Active Sketch cameras they are solids added to the scene's
objects (:func:`with_arm`), which that renderer sorts by depth itself.
"""

from __future__ import annotations

import msgspec
import numpy as np
from numpy.typing import NDArray

from umbra.connectors.messages import Poses
from umbra.connectors.scene_messages import SceneObjects, SolidKind
from umbra.modules.arm.arm_solids import arm_boxes, box_corners
from umbra.modules.vision.scene import RGB, Occluder

FloatArray = NDArray[np.float64]

#: the arm's links and the fingers (RGB): a light and a dark grey, unlike the patch and table
ARM_RGB: RGB = (175, 178, 185)
FINGER_RGB: RGB = (60, 62, 70)
#: a box no nearer than this in front of the lens is not drawn [m]
NEAR_M = 1e-3
#: faces of a box: corner indices (of :func:`box_corners`) and the outward axis (+-1, axis)
_FACES = (
    ((0, 1, 3, 2), (-1, 0)),
    ((4, 6, 7, 5), (1, 0)),
    ((0, 4, 5, 1), (-1, 1)),
    ((2, 3, 7, 6), (1, 1)),
    ((0, 2, 6, 4), (-1, 2)),
    ((1, 5, 7, 3), (1, 2)),
)


def arm_in(poses: Poses, T_world_frame: FloatArray) -> list[tuple[FloatArray, FloatArray, RGB]]:
    """The arm's boxes ``(T_world_box, size, rgb)`` from its frames (``poses``, in the frame
    ``T_world_frame`` places in the world)."""
    boxes = arm_boxes(poses.matrices, tuple(poses.children))
    count = sum(1 for c in poses.children if "finger" in c)
    out = []
    for i, (T, size) in enumerate(boxes):
        rgb = FINGER_RGB if i >= len(boxes) - count else ARM_RGB
        out.append((T_world_frame @ T, size, rgb))
    return out


def arm_occluders(
    boxes: list[tuple[FloatArray, FloatArray, RGB]], T_world_camera: FloatArray
) -> tuple[Occluder, ...]:
    """The faces of ``boxes`` that face the camera, farthest first, as world occluders."""
    T_world_camera = np.asarray(T_world_camera, dtype=float)
    eye, forward = T_world_camera[:3, 3], T_world_camera[:3, 2]
    faces: list[tuple[float, Occluder]] = []
    for T, size, rgb in boxes:
        corners = box_corners(T, size)
        if np.all((corners - eye) @ forward <= NEAR_M):
            continue  # wholly behind the lens (the forearm, seen from the wrist)
        for index, (sign, axis) in _FACES:
            normal = sign * T[:3, axis]
            quad = corners[list(index)]
            to_eye = eye - quad.mean(axis=0)
            facing = float(normal @ to_eye)
            if facing <= 0.0:
                continue  # turned away
            shade = 0.55 + 0.45 * facing / max(float(np.linalg.norm(to_eye)), 1e-9)
            red, green, blue = (int(min(255, c * shade)) for c in rgb)
            occluder = Occluder(quad, "world", (red, green, blue))
            faces.append((float(np.linalg.norm(to_eye)), occluder))
    faces.sort(key=lambda f: -f[0])
    return tuple(face for _, face in faces)


def with_arm(
    objects: SceneObjects, boxes: list[tuple[FloatArray, FloatArray, RGB]]
) -> SceneObjects:
    """``objects`` and the arm's boxes (already in the objects' frame) as one scene."""
    if not boxes:
        return objects
    names = tuple(f"arm{i}" for i in range(len(boxes)))
    return msgspec.structs.replace(
        objects,
        names=(*objects.names, *names),
        kinds=(*objects.kinds, *(SolidKind.BOX,) * len(boxes)),
        poses=np.concatenate([objects.poses, np.stack([b[0] for b in boxes])]),
        sizes=np.concatenate([objects.sizes, np.stack([b[1] for b in boxes])]),
        colors=np.concatenate(
            [objects.colors, np.array([b[2] for b in boxes], dtype=objects.colors.dtype)]
        ),
    )
