"""Active Sketch as a Python API on a simulated cell (no graph, no browser).

:class:`SketchSession` holds a randomizable scene (:mod:`umbra.modules.world.scene_objects`), the
two zoom cameras on their PTUs (:mod:`umbra.modules.sketch.rig`), a simulated Puma 560 with its
gripper, and runs the same pieces as the graph: snapshot -> primitives placed by pixels (epipolar
constraint, triangulation with covariance) -> macro menu -> checked plan -> the VCR player
whose twist goes through the velocity register (REG_VEL's logic) and the resolved-rate
kinematics (WOLVERINE_KIN's) to the simulated joints; the world's judge gives the verdicts.

Used by the CLI (``umbra sketch``), the benchmark and the tests. Metres, radians, seconds.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from umbra.connectors.path_messages import VCR_MOVING, ToolPath, VcrAction, VcrMode
from umbra.connectors.sketch_messages import Macro, SketchBox, SketchPrimitive, StereoSnapshot
from umbra.modules.arm.dh import puma560
from umbra.modules.arm.dls import DLSSettings, solve_dls
from umbra.modules.arm.jacobian import jacobian_and_pose, tool_twist_in_base
from umbra.modules.arm.sim_joints import SimJoints, SimJointSettings
from umbra.modules.arm.velocity_register import RegisterSettings, VelocityRegister
from umbra.modules.geometry.transforms import translation
from umbra.modules.ptu.sim_ptu import SimPtu
from umbra.modules.sketch.macros import MacroError, macro_keys, macro_named, menu_for
from umbra.modules.sketch.path_check import PathLimits, plan_path
from umbra.modules.sketch.primitives import place_primitive, triad_box
from umbra.modules.sketch.rig import RigCamera, default_rig
from umbra.modules.sketch.stereo import StereoNoise, StereoPair
from umbra.modules.trajectory.player import PathPlayer
from umbra.modules.trajectory.vcr import ACTIONS, ARGUMENT, VcrError, check_command
from umbra.modules.vision.sketch_render import render_scene
from umbra.modules.world.scene_objects import SketchScene
from umbra.modules.world.sketch_judge import SketchJudge

FloatArray = NDArray[np.float64]

#: ready: tool 0.26 m above the table, looking down; stow: folded back
Q_READY = np.radians([0.0, 45.6, -182.7, 0.0, -42.9, 0.0])
Q_STOW = np.radians([0.0, 80.0, -170.0, 0.0, -60.0, 0.0])
TOOL_XYZ = (0.0, 0.0, 0.14)


class SessionError(ValueError):
    """A session call that cannot be done (unknown id, failed plan)."""


@dataclass
class PlayLog:
    """Per tick of a play: time, VCR mode and parameter, joints, true tool point."""

    t: list[float] = field(default_factory=list)
    mode: list[str] = field(default_factory=list)
    s: list[float] = field(default_factory=list)
    s_dot: list[float] = field(default_factory=list)
    s_ddot: list[float] = field(default_factory=list)
    q: list[FloatArray] = field(default_factory=list)
    qd: list[FloatArray] = field(default_factory=list)
    tool: list[FloatArray] = field(default_factory=list)
    guard: list[str] = field(default_factory=list)

    def arrays(self) -> dict[str, np.ndarray]:
        return {k: np.asarray(v) for k, v in self.__dict__.items()}


class SketchSession:
    """A simulated Active Sketch cell (see module docstring)."""

    def __init__(
        self,
        scene: SketchScene | None = None,
        *,
        seed: int = 0,
        noise: StereoNoise | None = None,
        dt: float = 0.01,
        rig: tuple[RigCamera, RigCamera] | None = None,
        limits: PathLimits | None = None,
        image_noise: float = 2.0,
    ) -> None:
        self.rng = np.random.default_rng(seed)
        self.judge = SketchJudge(scene or SketchScene.random(self.rng))
        self.noise = noise or StereoNoise()
        self.dt = dt
        self.table = puma560()
        self.T_flange_tool = translation(*TOOL_XYZ)
        self.arm = SimJoints(self.table, Q_READY, SimJointSettings(gripper_travel_time=0.5))
        self.cameras = rig or default_rig()
        self.ptus = [SimPtu(c.geometry) for c in self.cameras]
        self.zooms = [0.0, 0.0]
        self.limits = limits or PathLimits()
        self.register = VelocityRegister(RegisterSettings(0.1, 0.1, 0.5))
        self.dls = DLSSettings(eps=0.04, lambda_max=0.04, limit_margin=np.radians(5.0))
        self.image_noise = image_noise
        self.time = 0.0
        self.snapshots: dict[str, StereoSnapshot] = {}
        self.primitives: dict[str, SketchPrimitive] = {}
        self.paths: dict[str, ToolPath] = {}
        self.boxes: dict[str, SketchBox] = {}
        self.player: PathPlayer | None = None
        self._watch: dict[str, FloatArray] = {}

    # -- world --------------------------------------------------------------------------------
    @property
    def scene(self) -> SketchScene:
        return self.judge.scene

    @property
    def T_base_tool(self) -> FloatArray:
        return self.table.fk(self.arm.q_reported, self.T_flange_tool)

    def camera_state(self, i: int):
        """(model, T_base_camera) of camera ``i`` (0 = a, 1 = b) now."""
        cam = self.cameras[i]
        model = cam.model(self.zooms[i])
        pan, tilt = self.ptus[i].angles
        return model, cam.T_base_camera(pan, tilt, model)

    def aim(self, point: ArrayLike, zoom: float | None = None, settle: bool = True) -> None:
        """Slew both PTUs to watch ``point`` (m, base); set the zoom (0 wide .. 1 tele); wait
        until they stop. Raises SessionError (nothing moves) for a point out of the units'
        travel or a zoom out of range."""
        p = np.asarray(point, dtype=float)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise SessionError(f"aim: expected a finite 3-D point (m, base), got {point!r}")
        if zoom is not None and not (np.isfinite(zoom) and 0.0 <= zoom <= 1.0):
            raise SessionError(f"aim: expected a zoom within 0 .. 1, got {zoom}")
        zooms = self.zooms if zoom is None else [float(zoom)] * 2
        try:  # each camera through its whole model at the zoom it will have
            angles = [c.aim(p, z) for c, z in zip(self.cameras, zooms, strict=True)]
        except ValueError as exc:
            raise SessionError(f"aim at {np.round(p, 3).tolist()} m: {exc}") from None
        for unit, (pan, tilt) in zip(self.ptus, angles, strict=True):
            unit.command(pan, tilt)
        if zoom is not None:
            self.zooms = [float(zoom), float(zoom)]
        while settle and any(u.moving for u in self.ptus):
            self._tick(np.zeros(6), "")

    def grip(self, action: str) -> None:
        """Open or close the gripper ("open" / "close") and wait until it gets there (the arm
        holds still); e.g. a device taken in hand before place_device."""
        if action not in ("open", "close"):
            raise SessionError(f"grip: expected open or close, got {action!r}")
        self._tick(np.zeros(6), action)
        while self.arm.gripper_moving:
            self._tick(np.zeros(6), "")

    # -- snapshots and primitives -------------------------------------------------------------
    def snapshot(self, snapshot_id: str | None = None, render: bool = True) -> StereoSnapshot:
        """Both images and camera models now (``render`` False: blank images, for speed)."""
        sid = snapshot_id or f"snap{len(self.snapshots) + 1}"
        objects = self.scene.message(self.time)
        parts = []
        for i in range(2):
            model, T = self.camera_state(i)
            if render:
                image = render_scene(
                    objects,
                    model.K,
                    T,
                    model.width,
                    model.height,
                    model.dist,
                    self.rng,
                    self.image_noise,
                )
            else:
                image = np.zeros((model.height, model.width, 3), np.uint8)
            parts.append((model, T, image))
        (ma, Ta, ia), (mb, Tb, ib) = parts
        snap = StereoSnapshot.of_pair(self.time, sid, (ma, ia, Ta), (mb, ib, Tb))
        self.snapshots[sid] = snap
        return snap

    def place(
        self,
        kind: str,
        pixels_a: ArrayLike,
        pixels_b: ArrayLike,
        snapshot_id: str | None = None,
        primitive_id: str | None = None,
    ) -> SketchPrimitive:
        """Place a primitive by its vertex pixels in both images of a snapshot (latest)."""
        snap = self._snapshot(snapshot_id)
        pid = primitive_id or f"{kind}{len(self.primitives) + 1}"
        prim = place_primitive(
            StereoPair.from_snapshot(snap),
            kind,
            pixels_a,
            pixels_b,
            self.noise,
            primitive_id=pid,
            snapshot_id=snap.snapshot_id,
            stamp=self.time,
        )
        self.primitives[pid] = prim
        return prim

    def true_pixels(self, points: ArrayLike, snapshot_id: str | None = None):
        """Where true 3-D points (m, base) appear in both images of a snapshot (px)."""
        pair = StereoPair.from_snapshot(self._snapshot(snapshot_id))
        return pair.project("a", points), pair.project("b", points)

    # -- macros -------------------------------------------------------------------------------
    def macros(self, primitive_id: str | None = None) -> list[tuple[Macro, str]]:
        return menu_for(self._primitive(primitive_id))

    def make_box(self, primitive_id: str) -> SketchBox:
        """The triad macro: keep the box the triad spans as scene geometry (no motion)."""
        prim = self._primitive(primitive_id)
        if prim is None or prim.kind != "triad":
            kind = prim.kind if prim is not None else "nothing"
            raise MacroError(f"make_box needs a triad, got {kind}")
        pair = StereoPair.from_snapshot(self._snapshot(prim.snapshot_id))
        box = triad_box(prim, pair=pair, noise=self.noise)
        self.boxes[box.box_id] = box
        return box

    def plan(
        self, macro: Macro | str, primitive_id: str | None = None, options: dict | None = None
    ) -> ToolPath:
        """Plan and check ``macro`` (a name is taken as its :class:`Macro`, MacroError if there
        is none) from the arm's current joints (``ok`` False: refused). ``make_box`` has no
        motion: use :meth:`make_box`."""
        macro = macro_named(macro)
        if macro == Macro.MAKE_BOX:
            raise MacroError("make_box has no motion to plan; call make_box(primitive_id)")
        prim = self._primitive(primitive_id)
        cam_a = self.camera_state(0)[1][:3, 3]
        keys = macro_keys(
            macro,
            prim,
            self.T_base_tool,
            self.arm.gripper_opening,
            options,
            q_ready=Q_READY,
            q_stow=Q_STOW,
            camera_centre=cam_a,
        )
        path = plan_path(
            keys,
            self.table,
            self.T_flange_tool,
            self.arm.q_reported,
            self.arm.gripper_opening,
            self.limits,
            path_id=f"path{len(self.paths) + 1}",
            stamp=self.time,
        )
        self.paths[path.path_id] = path
        watch = keys.watch
        if watch is None and len(path.T_base_tool):
            watch = np.asarray(path.T_base_tool[-1][:3, 3])  # canned motions: the tool's goal
        if watch is not None:
            self._watch[path.path_id] = watch
        return path

    # -- the VCR ------------------------------------------------------------------------------
    def load(self, path_id: str) -> PathPlayer:
        path = self.paths.get(path_id)
        if path is None:
            raise SessionError(f"no path {path_id!r}; planned: {sorted(self.paths)}")
        if not path.ok:
            raise SessionError(f"path {path_id} was refused: {path.reason}")
        if np.max(np.abs(path.joints[0] - self.arm.q_reported)) > 0.01:
            raise SessionError(f"the arm has moved since {path_id} was planned; plan again")
        self.player = PathPlayer(path, self.table, self.T_flange_tool)
        self.judge.reset_measures()
        return self.player

    def play(
        self,
        path_id: str,
        script: list[tuple[float, str, dict]] | None = None,
        timeout: float = 60.0,
        watch: bool = True,
    ) -> PlayLog:
        """Play a path: VCR ``script`` of (time after start [s], action, kwargs); default: play.

        Runs until the path is done and the gripper settled, or ``timeout``. When ``watch``, the
        cameras are slewed to watch the macro's goal as it starts (the report's behaviour).
        """
        if not (np.isfinite(timeout) and timeout > 0):
            raise SessionError(f"play: expected a timeout > 0 s, got {timeout}")
        steps = list(script or [(0.0, "play", {})])
        length = float(self.paths[path_id].s[-1]) if path_id in self.paths else 0.0
        for when, action, kwargs in steps:  # refuse a bad step before anything moves
            _check_step(when, action, kwargs, length)
        player = self.load(path_id)
        goal = self._watch.get(path_id)
        if watch and goal is not None:
            for cam, unit, z in zip(self.cameras, self.ptus, self.zooms, strict=True):
                with contextlib.suppress(ValueError):  # out of the units' travel: keep the view
                    unit.command(*cam.aim(goal, z))
        pending = sorted(steps, key=lambda e: e[0])
        log = PlayLog()
        start = self.time
        settle = 0
        while self.time - start < timeout:
            while pending and pending[0][0] <= self.time - start + 1e-9:
                _, action, kwargs = pending.pop(0)
                player.command(VcrAction(action), **kwargs, q_measured=self.arm.q_reported)
            out = player.step(self.dt, self.arm.q_reported)
            guard = self._tick(out.twist_tool, out.gripper)
            if guard and out.mode in VCR_MOVING:
                player.halt(f"guard stop: {guard}", freeze=True)
            log.t.append(self.time - start)
            log.mode.append(out.mode)
            log.s.append(out.s)
            log.s_dot.append(out.s_dot)
            log.s_ddot.append(out.s_ddot)
            log.q.append(self.arm.q_reported)
            log.qd.append(self.arm.qd)
            log.tool.append(self.T_base_tool[:3, 3])
            log.guard.append(guard)
            if out.mode == VcrMode.DONE and not pending and not self.arm.gripper_moving:
                settle += 1
                if settle > int(0.3 / self.dt):
                    break
        return log

    def _tick(self, twist_tool: FloatArray, gripper: str | None) -> str:
        """One control period: register (watchdog, clamps) -> DLS -> joints -> world; a
        ``gripper`` action ("open" / "close"; empty or None: none) is commanded first."""
        self.register.put(twist_tool, self.time)
        reg = self.register.output(self.time)
        q = self.arm.q_reported
        J, T = jacobian_and_pose(self.table, q, self.T_flange_tool)
        rates = solve_dls(
            J,
            tool_twist_in_base(T, reg.twist),
            q,
            self.table.q_min,
            self.table.q_max,
            self.table.qd_max,
            self.dls,
        ).rates
        if gripper:
            self.arm.command_gripper(gripper)
        self.arm.step(rates, self.dt)
        for unit in self.ptus:
            unit.step(self.dt)
        self.time += self.dt
        T_true = self.table.fk(self.arm.q_true, self.T_flange_tool)
        self.judge.update(T_true, self.arm.gripper_opening)
        return reg.zero_reason

    # -- lookups ------------------------------------------------------------------------------
    def _snapshot(self, snapshot_id: str | None) -> StereoSnapshot:
        if not self.snapshots:
            raise SessionError("no snapshot taken yet")
        sid = snapshot_id or list(self.snapshots)[-1]
        if sid not in self.snapshots:
            raise SessionError(f"no snapshot {sid!r}; taken: {sorted(self.snapshots)}")
        return self.snapshots[sid]

    def _primitive(self, primitive_id: str | None) -> SketchPrimitive | None:
        if primitive_id is None:
            return None
        if primitive_id not in self.primitives:
            raise MacroError(f"no primitive {primitive_id!r}; placed: {sorted(self.primitives)}")
        return self.primitives[primitive_id]


def _check_step(when: float, action: str, kwargs: dict, length: float) -> None:
    """A VCR script step: time (s after the start), action and its speed (0.1 .. 1) or seek
    target (0 .. ``length``, path units)."""
    where = f"script step {when}:{action}"
    if not (np.isfinite(when) and when >= 0):
        raise SessionError(f"{where}: expected a time >= 0 s, got {when}")
    known = VcrAction(action) if action in ACTIONS else None
    takes = "" if known is None else ARGUMENT[known]
    unknown = set(kwargs) - {takes}
    if known is not None and unknown:
        raise SessionError(f"{where}: takes {takes or 'nothing'}, got {sorted(unknown)}")
    try:
        check_command(action, kwargs.get("speed"), kwargs.get("s"), length)
    except VcrError as exc:
        raise SessionError(f"{where}: {exc}") from None
