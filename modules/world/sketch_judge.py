"""The world's truth and verdicts for Active Sketch macros.

Fed with the TRUE tool pose and gripper opening every tick, :class:`SketchJudge` moves what the
gripper moves (the door follows a grasped handle) and measures each macro's outcome against the
true scene:

* grasp (Grab Pipe): when the gripper closes, the tool point's distance from the pipe axis (m)
  and the angle (rad) between the tool's x axis (across the fingers) and the pipe axis;
  success within 5 mm and 3 deg, the grasp inside the pipe's length;
* door (Move Around Axis): the handle (a horizontal bar) is held when the gripper closed within
  8 mm of its axis with the tool's x axis within 10 deg of it; while held, the door turns so
  that the handle follows the tool; the handle is lost when the tool leaves it by more than
  15 mm; success when the door reached 80 deg without losing the handle;
* surface scan: coverage of the true rectangle by the sensor footprint (radius ``footprint``)
  while the tool is at the standoff (within 1 cm) and looks down (within 10 deg);
* perimeter: the largest distance of the tool's footprint centre from the true outline while at
  the standoff, and the fraction of the outline passed within 5 mm;
* place device: where the device (the tool point) is released, against the spot in front of
  the package's front face.

Tool frame (as the planner builds it): z = approach, y = finger closing, x = across the fingers.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from umbra.connectors.sketch_messages import Macro
from umbra.modules.world.scene_objects import SketchScene

FloatArray = NDArray[np.float64]

GRASP_TOLERANCE_M = 0.005
GRASP_TOLERANCE_RAD = np.radians(3.0)
DOOR_GOAL_RAD = np.radians(80.0)
DOOR_MAX_RAD = np.radians(110.0)
HANDLE_CATCH_M = 0.008
HANDLE_LOSE_M = 0.015
BAND_M = 0.01
PERIMETER_TOLERANCE_M = 0.005
#: macros that grasp (the pipe): judged when the gripper closes
GRASP_MACROS = (Macro.GRAB_PIPE, Macro.APPROACH_SIDE)
#: share of the surface scanned, or of the outline followed, that counts as a success
COVERAGE_GOAL = 0.95
DEVICE_STANDOFF_M = 0.08
DEVICE_HALF_HEIGHT_M = 0.03
DEVICE_TOLERANCE_M = 0.01


@dataclass
class Verdicts:
    """Measured outcomes (NaN until measured)."""

    grasp_distance_m: float = float("nan")
    grasp_angle_rad: float = float("nan")
    grasp_inside: bool = False
    handle_held: bool = False
    handle_lost: bool = False
    door_max_rad: float = 0.0
    coverage: float = 0.0
    perimeter_max_dev_m: float = 0.0
    perimeter_passed: float = 0.0
    device_error_m: float = float("nan")
    #: distance of the tool point from the pipe axis at the last close, wherever it was [m]
    closed_distance_m: float = float("nan")
    #: distance of the tool point from the handle's axis when the gripper caught it [m]
    handle_distance_m: float = float("nan")
    closes: int = 0  #: gripper closings seen since the macro started
    opens: int = 0  #: gripper openings seen since the macro started
    events: list[str] = field(default_factory=list)

    def success(self, macro: Macro) -> bool:
        """Did ``macro`` succeed (per the benchmark's criteria)?"""
        if macro in GRASP_MACROS:
            return bool(
                self.grasp_inside
                and self.grasp_distance_m <= GRASP_TOLERANCE_M
                and self.grasp_angle_rad <= GRASP_TOLERANCE_RAD
            )
        if macro == Macro.MOVE_AROUND_AXIS:
            return bool(self.door_max_rad >= DOOR_GOAL_RAD - 1e-9 and not self.handle_lost)
        if macro == Macro.SURFACE_SCAN:
            return self.coverage >= COVERAGE_GOAL
        if macro == Macro.FOLLOW_PERIMETER:
            return bool(
                self.perimeter_max_dev_m <= PERIMETER_TOLERANCE_M
                and self.perimeter_passed >= COVERAGE_GOAL
            )
        if macro == Macro.PLACE_DEVICE:
            return bool(self.device_error_m <= DEVICE_TOLERANCE_M)
        return False


class SketchJudge:
    """Truth of the scene as the arm acts on it, and the verdicts (see module docstring)."""

    def __init__(self, scene: SketchScene, standoff: float = 0.08, footprint: float = 0.02) -> None:
        self.scene = scene
        self.standoff = standoff
        self.footprint = footprint
        self.verdicts = Verdicts()
        self._gripper_closed: bool | None = None
        self._handle_held = False
        self._cell = 0.004
        s = scene.surface
        nx, ny = int(np.ceil(s.size[0] / self._cell)), int(np.ceil(s.size[1] / self._cell))
        gx = (np.arange(nx) + 0.5) * self._cell - s.size[0] / 2
        gy = (np.arange(ny) + 0.5) * self._cell - s.size[1] / 2
        self._grid = np.stack(np.meshgrid(gx, gy, indexing="ij"), axis=-1).reshape(-1, 2)
        self._covered = np.zeros(len(self._grid), dtype=bool)
        self._outline = self._outline_points(s.size)
        self._outline_passed = np.zeros(len(self._outline), dtype=bool)

    def reset_measures(self) -> None:
        """Start measuring a new macro (the door keeps its angle, the handle its grip)."""
        self.verdicts = Verdicts(handle_held=self._handle_held, door_max_rad=self.scene.door.angle)
        self._covered[:] = False
        self._outline_passed[:] = False

    # -- the world's step ---------------------------------------------------------------------
    def update(self, T_base_tool: FloatArray, gripper_opening: float) -> None:
        """One tick of the true tool pose (4 x 4, m) and gripper opening (0 closed .. 1 open)."""
        closed = gripper_opening < 0.5
        if self._gripper_closed is not None and closed != self._gripper_closed:
            if closed:
                self._on_close(T_base_tool)
            else:
                self._on_open(T_base_tool)
        self._gripper_closed = closed
        if self._handle_held and closed:
            self._drag_door(T_base_tool[:3, 3])
        self._measure_surface(T_base_tool)

    def _on_close(self, T: FloatArray) -> None:
        v = self.verdicts
        p, x_axis = T[:3, 3], T[:3, 0]
        pipe = self.scene.pipe
        rel = p - pipe.center
        along = float(rel @ pipe.axis)
        distance = float(np.linalg.norm(rel - along * pipe.axis))
        v.closes += 1
        v.closed_distance_m = distance
        if distance < 0.05:
            v.grasp_distance_m = distance
            v.grasp_angle_rad = float(np.arccos(min(1.0, abs(float(x_axis @ pipe.axis)))))
            v.grasp_inside = abs(along) <= pipe.length / 2 - 0.02
            v.events.append(
                f"gripper closed {distance * 1e3:.2f} mm from the pipe axis, "
                f"{np.degrees(v.grasp_angle_rad):.2f} deg off it"
            )
        door = self.scene.door
        rel_h = p - door.handle_center
        along_h = float(rel_h @ door.handle_axis)
        off_axis = float(np.linalg.norm(rel_h - along_h * door.handle_axis))
        if (
            off_axis <= HANDLE_CATCH_M
            and abs(along_h) <= door.handle_length / 2
            and abs(x_axis @ door.handle_axis) >= np.cos(np.radians(10.0))
        ):
            self._handle_held = v.handle_held = True
            v.handle_distance_m = off_axis
            v.events.append(f"handle held ({off_axis * 1e3:.1f} mm from its axis)")

    def _on_open(self, T: FloatArray) -> None:
        v = self.verdicts
        v.opens += 1
        if self._handle_held:
            self._handle_held = False
            v.events.append(f"handle released at {np.degrees(self.scene.door.angle):.1f} deg")
        pkg = self.scene.package
        edge = pkg.front_bottom_edge.mean(axis=0)
        target = edge + DEVICE_STANDOFF_M * pkg.outward + [0.0, 0.0, DEVICE_HALF_HEIGHT_M]
        error = float(np.linalg.norm(T[:3, 3] - target))
        if error < 0.1:
            v.device_error_m = error
            v.events.append(f"device released {error * 1e3:.1f} mm from its spot")

    def _drag_door(self, p: FloatArray) -> None:
        door = self.scene.door
        rel = (p - door.hinge)[:2]
        closed = door.handle_rest_xy
        angle = float(-(np.arctan2(rel[1], rel[0]) - np.arctan2(closed[1], closed[0])))
        angle = float((angle + np.pi) % (2 * np.pi) - np.pi)
        angle = float(np.clip(angle, 0.0, DOOR_MAX_RAD))
        self.scene = self.scene.with_door_angle(angle)
        gap = float(np.linalg.norm(p - self.scene.door.handle_center))
        v = self.verdicts
        v.door_max_rad = max(v.door_max_rad, angle)
        if gap > HANDLE_LOSE_M:
            self._handle_held = False
            v.handle_lost = True
            v.events.append(f"handle lost at {np.degrees(angle):.1f} deg ({gap * 1e3:.1f} mm)")

    def _measure_surface(self, T: FloatArray) -> None:
        s = self.scene.surface
        height = float(T[2, 3] - s.center[2])
        if abs(height - self.standoff) > BAND_M or T[2, 2] > -np.cos(np.radians(10.0)):
            return
        c, si = np.cos(s.yaw), np.sin(s.yaw)
        d = T[:2, 3] - s.center[:2]
        local = np.array([c * d[0] + si * d[1], -si * d[0] + c * d[1]])
        near = np.linalg.norm(self._grid - local, axis=1) <= self.footprint
        self._covered |= near
        v = self.verdicts
        v.coverage = float(self._covered.mean())
        dev = self._distance_to_outline(local, s.size)
        if dev <= 0.03:  # following the outline, not crossing the middle
            v.perimeter_max_dev_m = max(v.perimeter_max_dev_m, dev)
            self._outline_passed |= (
                np.linalg.norm(self._outline - local, axis=1) <= PERIMETER_TOLERANCE_M
            )
            v.perimeter_passed = float(self._outline_passed.mean())

    @staticmethod
    def _outline_points(size: tuple[float, float]) -> FloatArray:
        hx, hy = size[0] / 2, size[1] / 2
        corners = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy], [-hx, -hy]])
        pts = [np.linspace(corners[i], corners[i + 1], 60, endpoint=False) for i in range(4)]
        return np.concatenate(pts)

    @staticmethod
    def _distance_to_outline(local: FloatArray, size: tuple[float, float]) -> float:
        hx, hy = size[0] / 2, size[1] / 2
        x, y = abs(local[0]), abs(local[1])
        if x <= hx and y <= hy:
            return float(min(hx - x, hy - y))
        return float(np.hypot(max(x - hx, 0.0), max(y - hy, 0.0)))
