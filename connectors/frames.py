"""Static frames of a graph: named rigid transforms, looked up by chaining through the tree.

``frames: {tool->camera: {xyz: [0, 0.05, 0.1], rpy_deg: [0, 0, 90]}}`` in a graph declares
T_tool_camera, the pose of ``camera`` in ``tool``: translation ``xyz`` [m] and a rotation given as
roll, pitch, yaw [deg] about the fixed x, y, z axes (R = Rz(yaw) Ry(pitch) Rx(roll), the ROS/URDF
convention), converted once.
"""

from __future__ import annotations

import re
from collections import deque

import numpy as np

#: What a graph may name a frame, a module or a process: an identifier.
NAME_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


def frame_name_problem(name: str) -> str:
    """Why ``name`` cannot name a frame in a graph (``frames: {parent->child: ...}``); empty when
    it can."""
    if NAME_RE.match(name):
        return ""
    return (
        f"frame name {name!r} must be an identifier (letters, digits and `_`, not starting with a "
        "digit), as a graph's `frames:` requires"
    )


def transform_from_xyz_rpy(xyz: list[float], rpy_rad: list[float]) -> np.ndarray:
    """4 x 4 transform from a translation [m] and fixed-axis roll, pitch, yaw [rad]:
    R = Rz(yaw) Ry(pitch) Rx(roll)."""
    (cr, cp, cy), (sr, sp, sy) = np.cos(rpy_rad), np.sin(rpy_rad)
    T = np.eye(4)
    T[:3, :3] = [
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [0.0 - sp, cp * sr, cp * cr],  # 0.0 - sp: no negative zero
    ]
    T[:3, 3] = xyz
    return T


class FrameTree:
    """A set of static transforms T_parent_child; ``lookup(a, b)`` returns T_a_b."""

    def __init__(self) -> None:
        self._edges: dict[str, dict[str, np.ndarray]] = {}
        self._chains: dict[tuple[str, str], np.ndarray] = {}  # lookups so far (frames are static)

    def add(self, parent: str, child: str, T_parent_child: np.ndarray) -> None:
        """Declare the pose of ``child`` in ``parent``."""
        T = np.asarray(T_parent_child, dtype=float)
        self._chains.clear()
        self._edges.setdefault(parent, {})[child] = T
        self._edges.setdefault(child, {})[parent] = np.linalg.inv(T)

    @property
    def names(self) -> set[str]:
        """Every frame named in the tree."""
        return set(self._edges)

    def lookup(self, parent: str, child: str) -> np.ndarray:
        """T_parent_child by chaining static transforms (a fresh array, computed once per pair);
        KeyError when they are not connected."""
        chain = self._chains.get((parent, child))
        if chain is None:
            chain = self._chains[(parent, child)] = self._chain(parent, child)
        fresh: np.ndarray = chain.copy()
        return fresh

    def _chain(self, parent: str, child: str) -> np.ndarray:
        if parent == child:
            return np.eye(4)
        seen = {parent: np.eye(4)}
        queue = deque([parent])
        while queue:
            name = queue.popleft()
            for nxt, T in self._edges.get(name, {}).items():
                if nxt in seen:
                    continue
                seen[nxt] = seen[name] @ T
                if nxt == child:
                    return seen[nxt]
                queue.append(nxt)
        raise KeyError(f"no chain of static frames from `{parent}` to `{child}`")

    def has(self, parent: str, child: str) -> bool:
        """Whether ``lookup(parent, child)`` would succeed."""
        try:
            self.lookup(parent, child)
        except KeyError:
            return False
        return True
