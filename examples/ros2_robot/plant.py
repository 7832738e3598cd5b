"""The robot's physics and sight, from umbra's pure simulation (no ports, no messages): a Puma 560
whose joints obey velocity commands under a drive watchdog (``SimJoints``), a wrist camera that
renders the tool's tray (``SimulatedCamera``, the arm's fingers drawn over it), and the judge of
the grasp, who knows the truth (``grasp_error``, with the World module's tolerances).

It is what ``graphs/tool_pickup.yaml``'s World, WOLVERINE_JNTS (``backend: sim``) and DigiCam
(``source: sim``) simulate there, set up the same: the arm's initial pose and calibration error,
the tool's place, the camera's intrinsics and noise.

Frames: ``base`` (the robot's base), ``flange``, ``tool`` (the gripper's centre point),
``camera`` (on the tool, looking along its z), ``table`` (the table top, z up, the camera's
world) and ``patch`` (the tool's colored patch). Units: m, rad, s.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from umbra.connectors.messages import Poses
from umbra.modules.arm.arm_solids import TRUE_PREFIX, arm_frames
from umbra.modules.arm.dh import puma560
from umbra.modules.arm.sim_joints import SimJoints, SimJointSettings
from umbra.modules.geometry.transforms import transform_from_xyz_rpy_deg
from umbra.modules.vision.arm_view import arm_in, arm_occluders
from umbra.modules.vision.lighting import Lighting
from umbra.modules.vision.scene import Scene
from umbra.modules.vision.sim_camera import CameraSpec, SimulatedCamera
from umbra.modules.world.grasp import grasp_error
from umbra.modules.world.world import T_table_patch_of, WorldParams

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class RobotSetup:
    """The robot and its scene, as ``graphs/tool_pickup.yaml`` sets them up."""

    initial_q_deg: tuple[float, ...] = (14.482, 45.603, -182.743, 0.0, -42.86, -165.518)
    calibration_error_deg: tuple[float, ...] = (0.8, -0.6, 0.9, -0.5, 0.7, -0.4)
    tool_xyz_m: tuple[float, float, float] = (0.0, 0.0, 0.14)  #: tool point in the flange
    camera_in_tool_m: tuple[float, float, float] = (0.0, 0.0, -0.12)  #: camera in the tool
    table_in_base_m: tuple[float, float, float] = (0.0, 0.0, 0.25)  #: table top in the base
    tool_xy_m: tuple[float, float] = (0.63, -0.04)  #: the patch's centre on the table
    tool_yaw_deg: float = 20.0
    patch_height_m: float = 0.03
    patch_size_m: tuple[float, float] = (0.06, 0.04)
    #: fx, fy, u0, v0 [px], width, height [px] of the wrist camera
    intrinsics: tuple[float, float, float, float, int, int] = (800, 800, 640, 360, 1280, 720)
    noise_sigma: float = 3.0  #: sensor noise [gray levels]
    watchdog_s: float = 0.1  #: the drive obeys a velocity command this long at most


@dataclass(frozen=True)
class Frame:
    """One camera frame: BGR pixels and the patch's true outline in it [px] (N x 2)."""

    pixels: NDArray[np.uint8]
    outline: FloatArray


@dataclass
class Verdict:
    """The grasp as judged against the truth."""

    grasped: bool = False
    judged: bool = False
    position_error_mm: float = float("nan")
    roll_error_deg: float = float("nan")
    verdict: str = "no grasp attempted"
    extra: dict[str, object] = field(default_factory=dict)


class RobotPlant:
    """Joints, camera and judge of the simulated robot; thread-safe (one lock)."""

    def __init__(self, setup: RobotSetup = RobotSetup(), seed: int = 1) -> None:
        self.setup = setup
        self.table = puma560()
        settings = SimJointSettings(
            calibration_error=tuple(np.radians(setup.calibration_error_deg)),
            watchdog=setup.watchdog_s,
        )
        self._joints = SimJoints(self.table, np.radians(setup.initial_q_deg), settings)
        self._lock = threading.Lock()
        self.T_flange_tool = transform_from_xyz_rpy_deg(list(setup.tool_xyz_m), [0, 0, 0])
        T_tool_camera = transform_from_xyz_rpy_deg(list(setup.camera_in_tool_m), [0, 0, 0])
        self.T_flange_camera = self.T_flange_tool @ T_tool_camera
        T_base_table = transform_from_xyz_rpy_deg(list(setup.table_in_base_m), [0, 0, 0])
        self.T_table_base = np.linalg.inv(T_base_table)
        self.T_table_patch = T_table_patch_of(
            list(setup.tool_xy_m), float(np.radians(setup.tool_yaw_deg)), setup.patch_height_m
        )
        fx, fy, u0, v0, width, height = setup.intrinsics
        self.spec = CameraSpec.from_values(fx, fy, 0.0, u0, v0, width, height, [])
        self._camera = SimulatedCamera()
        self._lighting = Lighting(noise_sigma=setup.noise_sigma)
        self._rng = np.random.default_rng(seed)
        world = WorldParams.model_fields
        self.position_tolerance_mm = float(world["position_tolerance_mm"].default)
        self.roll_tolerance_deg = float(world["roll_tolerance_deg"].default)
        self._closing_seen = False
        self._t: float | None = None  #: the time [s] the drive has been run to
        self.verdict = Verdict()
        self.commands = 0

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(self.table.names)

    # -- commands --------------------------------------------------------------------------------
    def command_rates(self, rates: FloatArray, now: float) -> None:
        """Joint velocities [rad/s] that arrived at ``now`` [s], obeyed from then for the
        watchdog's time at most (the drive runs to ``now`` under the command before)."""
        with self._lock:
            self._run_to(now)
            self._joints.hold(rates)
            self.commands += 1

    def command_gripper(self, action: str, now: float) -> None:
        """``open`` or ``close``, arrived at ``now`` [s]."""
        with self._lock:
            self._run_to(now)
            self._joints.command_gripper(action)

    # -- time ------------------------------------------------------------------------------------
    def _run_to(self, now: float) -> None:
        if self._t is not None and now > self._t:
            self._joints.advance(now - self._t, 0.002)
        self._t = now if self._t is None else max(self._t, now)

    def advance(self, now: float) -> None:
        """Run the drive to ``now`` [s] (monotonic), then judge the grasp once the gripper has
        closed."""
        with self._lock:
            self._run_to(now)
            gripper = self._joints.gripper_opening
            if self.verdict.judged:
                return
            if gripper < 0.99:
                self._closing_seen = True
            if self._closing_seen and gripper <= 0.0:
                self._judge(self._joints.q_true)

    def joint_state(self) -> tuple[FloatArray, FloatArray, float]:
        """What the encoders report: positions [rad], velocities [rad/s], gripper opening."""
        with self._lock:
            j = self._joints
            return j.q_reported, j.qd, j.gripper_opening

    @property
    def watchdog_stops(self) -> int:
        return self._joints.watchdog_stops

    # -- sight -----------------------------------------------------------------------------------
    def _true_frames(self, q_true: FloatArray, gripper: float) -> tuple[FloatArray, tuple]:
        return arm_frames(self.table, q_true, self.T_flange_tool, gripper, self.T_table_base)

    def capture(self) -> Frame:
        """A frame of the wrist camera at the arm's true pose now (rendering takes its time; the
        pose is taken first, so the frame shows the instant this was called)."""
        with self._lock:
            q_true, gripper = self._joints.q_true, self._joints.gripper_opening
        matrices, children = self._true_frames(q_true, gripper)
        T_table_camera = matrices[children.index(TRUE_PREFIX + "flange")] @ self.T_flange_camera
        arm = Poses(matrices=matrices, children=children, frame="table")
        faces = arm_occluders(arm_in(arm, np.eye(4)), T_table_camera)
        scene = Scene(
            T_world_patch=self.T_table_patch,
            patch_size_m=self.setup.patch_size_m,
            background="photo",
            occluders=faces,
        )
        frame = self._camera.render(self.spec, scene, T_table_camera, self._lighting, self._rng)
        return Frame(pixels=frame.image, outline=frame.patch_polygon)

    # -- judge -----------------------------------------------------------------------------------
    def _judge(self, q_true: FloatArray) -> None:
        matrices, children = self._true_frames(q_true, 0.0)
        err = grasp_error(matrices[children.index(TRUE_PREFIX + "tool")], self.T_table_patch)
        ok = (
            err.position_mm <= self.position_tolerance_mm
            and abs(err.roll_deg) <= self.roll_tolerance_deg
        )
        word = "grasped" if ok else "missed"
        self.verdict = Verdict(
            grasped=ok,
            judged=True,
            position_error_mm=round(err.position_mm, 4),
            roll_error_deg=round(err.roll_deg, 4),
            verdict=f"{word}: tool point {err.position_mm:.2f} mm from the grasp point, roll "
            f"error {err.roll_deg:.2f} deg (tolerance {self.position_tolerance_mm:g} mm, "
            f"{self.roll_tolerance_deg:g} deg)",
            extra={
                "tilt_deg": round(float(np.degrees(err.tilt)), 4),
                "offset_patch_mm": [round(v * 1e3, 3) for v in err.offset_patch],
            },
        )
