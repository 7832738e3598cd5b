"""The arm as a few boxes, for the simulated cameras to draw where the arm really is.

:func:`arm_frames` (the plant's side: the TRUE joints) gives the frames a renderer needs, as one
:class:`~umbra.connectors.messages.Poses`: every DH link frame (``link1`` ... ``flange``), the
``tool`` frame, and one frame per gripper finger (``finger_a``, ``finger_b``: the finger's centre,
moved along the tool's y axis by the gripper opening). :func:`arm_boxes` (the renderer's side) turns
those frames into boxes ``(T_frame_box, size)``: a bone between consecutive link origins (links
of a spherical wrist share one: no bone), the wrist body on the flange along the tool's approach
axis, and the two fingers. One home for the sizes, so what is published and what is drawn agree.

Tool frame as the planners build it: z = approach (the fingertips at the tool point, z = 0), y =
finger closing, x = across the fingers. Lengths in metres.
"""

from __future__ import annotations

import itertools

import numpy as np
from numpy.typing import ArrayLike, NDArray

from umbra.modules.arm.dh import DHTable

FloatArray = NDArray[np.float64]

#: cross-section of a bone between two link origins [m]
BONE_WIDTH_M = 0.07
#: bones shorter than this are not drawn (coincident origins of a spherical wrist) [m]
MIN_BONE_M = 0.02
#: the wrist body on the flange: cross-section and length along the tool's z axis [m]
WRIST_SIZE_M = (0.08, 0.08, 0.05)
#: a finger: across (tool x), thickness (tool y), length (tool z, ending at the tool point) [m]
FINGER_SIZE_M = (0.014, 0.01, 0.07)
#: the gap between the fingers' inner faces, closed and fully open [m]
FINGER_GAP_M = (0.0, 0.1)
FINGERS = ("finger_a", "finger_b")
#: The plant's frames are named apart from the arm's estimated ones (WOLVERINE_KIN's
#: ``link_poses``: ``link1`` ... ``tool``), which differ by the calibration error: one name, one
#: parent, in a recording's and a viewer's tf tree.
TRUE_PREFIX = "true_"


def finger_offsets(opening: float) -> FloatArray:
    """Centres (2 x 3, tool frame, m) of the two fingers at gripper ``opening`` (0 closed .. 1
    open)."""
    closed, wide = FINGER_GAP_M
    gap = closed + (wide - closed) * float(np.clip(opening, 0.0, 1.0))
    y = gap / 2 + FINGER_SIZE_M[1] / 2
    z = -FINGER_SIZE_M[2] / 2
    return np.array([[0.0, -y, z], [0.0, y, z]])


def arm_frames(
    table: DHTable,
    q: ArrayLike,
    T_flange_tool: ArrayLike,
    opening: float,
    T_frame_base: ArrayLike | None = None,
    prefix: str = TRUE_PREFIX,
) -> tuple[FloatArray, tuple[str, ...]]:
    """``(matrices, children)``: T_frame_link of every link frame, the tool and the fingers at
    joints ``q`` [rad] and gripper ``opening``; ``frame`` is the base unless ``T_frame_base``;
    each child's name starts with ``prefix``."""
    A = table.link_transforms(q)
    T = np.eye(4) if T_frame_base is None else np.asarray(T_frame_base, dtype=float)
    links = []
    for a in A:
        T = T @ a
        links.append(T)
    T_tool = links[-1] @ np.asarray(T_flange_tool, dtype=float)
    fingers = []
    for offset in finger_offsets(opening):
        T_finger = T_tool.copy()
        T_finger[:3, 3] = T_tool[:3, :3] @ offset + T_tool[:3, 3]
        fingers.append(T_finger)
    names = (*[f"link{i + 1}" for i in range(len(A) - 1)], "flange", "tool", *FINGERS)
    return np.stack([*links, T_tool, *fingers]), tuple(prefix + name for name in names)


def arm_boxes(
    matrices: ArrayLike, children: tuple[str, ...]
) -> list[tuple[FloatArray, FloatArray]]:
    """Boxes ``(T_frame_box (4 x 4), size (3,))`` of the arm in the frames of
    :func:`arm_frames` (see the module docstring); frames it does not know are ignored."""
    M = np.asarray(matrices, dtype=float)
    names = [c[len(TRUE_PREFIX) :] if c.startswith(TRUE_PREFIX) else c for c in children]
    by_name = dict(zip(names, M, strict=True))
    chain = [by_name[n] for n in names if n.startswith("link") or n == "flange"]
    boxes: list[tuple[FloatArray, FloatArray]] = []
    for T0, T1 in itertools.pairwise(chain):
        start, end = T0[:3, 3], T1[:3, 3]
        length = float(np.linalg.norm(end - start))
        if length >= MIN_BONE_M:
            boxes.append((_along(start, end), np.array([BONE_WIDTH_M, BONE_WIDTH_M, length])))
    if "flange" in by_name and "tool" in by_name:
        T_wrist = by_name["tool"].copy()
        T_wrist[:3, 3] = by_name["flange"][:3, 3] + T_wrist[:3, 2] * WRIST_SIZE_M[2] / 2
        boxes.append((T_wrist, np.array(WRIST_SIZE_M)))
    boxes += [(by_name[f], np.array(FINGER_SIZE_M)) for f in FINGERS if f in by_name]
    return boxes


def box_corners(T_frame_box: ArrayLike, size: ArrayLike) -> FloatArray:
    """The 8 corners (8 x 3, m) of a box of edge lengths ``size`` centred on its pose."""
    half = np.asarray(size, dtype=float) / 2
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
    T = np.asarray(T_frame_box, dtype=float)
    return (signs * half) @ T[:3, :3].T + T[:3, 3]


def _along(start: FloatArray, end: FloatArray) -> FloatArray:
    """A pose centred between ``start`` and ``end`` with its z axis from one to the other."""
    z = (end - start) / np.linalg.norm(end - start)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    T[:3, 3] = (start + end) / 2
    return T
