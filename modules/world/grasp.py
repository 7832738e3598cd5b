"""Judging a grasp against the truth: where the gripper closed versus where the tool is.

Frames: ``base`` (robot base), ``patch`` (centre of the colored patch on the tool, z out of the
tool's top face, x along the patch's long side), ``tool`` (the gripper's centre point between the
fingertips, z along the approach direction). A perfect grasp puts the tool point on the patch
centre with the gripper's z opposite the patch normal and its x along the patch's long side; a
rectangle looks the same turned by 180°, so roll is compared modulo π.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from umbra.modules.geometry.polygon_moments import wrap_axis_angle

FloatArray = NDArray[np.float64]

#: R_patch_tool at a perfect grasp: x along the patch's x, z into the patch (Rx(π)).
R_PATCH_TOOL_GRASP = np.diag([1.0, -1.0, -1.0])


@dataclass(frozen=True)
class GraspError:
    """Position error [m] of the tool point, roll error [rad] about the patch normal, and tilt
    [rad] between the approach direction and the patch normal."""

    position: float
    roll: float
    tilt: float
    offset_patch: tuple[float, float, float]  #: tool point in patch coordinates [m]

    @property
    def position_mm(self) -> float:
        return self.position * 1e3

    @property
    def roll_deg(self) -> float:
        return float(np.degrees(self.roll))


def grasp_error(T_base_tool: FloatArray, T_base_patch: FloatArray) -> GraspError:
    """How far the gripper's tool frame is from a perfect grasp of the patch."""
    T_patch_tool = np.linalg.inv(T_base_patch) @ T_base_tool
    offset = T_patch_tool[:3, 3]
    R = T_patch_tool[:3, :3] @ R_PATCH_TOOL_GRASP.T  # identity at a perfect grasp
    roll = wrap_axis_angle(float(np.arctan2(R[1, 0], R[0, 0])))  # modulo π
    approach = T_patch_tool[:3, 2]  # tool z in patch coordinates, ideally (0, 0, -1)
    tilt = float(np.arccos(np.clip(-approach[2], -1.0, 1.0)))
    offset_patch = (float(offset[0]), float(offset[1]), float(offset[2]))
    return GraspError(float(np.linalg.norm(offset)), roll, tilt, offset_patch)
