"""SketchWorld: the simulated plant of Active Sketch, the scene's truth and the macros' verdicts."""

from __future__ import annotations

import numpy as np

from umbra.connectors import Input, Module, Output, param
from umbra.connectors.messages import JointState, Poses, Status
from umbra.connectors.path_messages import ToolPath, VcrMode, VcrState
from umbra.connectors.scene_messages import SceneObjects
from umbra.connectors.sketch_messages import Macro
from umbra.connectors.states import Verdict
from umbra.modules.arm.arm_params import ArmParams
from umbra.modules.arm.arm_solids import arm_frames
from umbra.modules.geometry.transforms import transform_from_xyz_rpy_deg
from umbra.modules.world.operator_stop import STOPPED_BY_OPERATOR, OperatorStop, operator_input
from umbra.modules.world.scene_objects import SketchScene
from umbra.modules.world.sketch_judge import SketchJudge
from umbra.modules.world.sketch_verdict import GRASP_MACROS, RELEASE_MACROS, macro_verdict


class SketchWorld(Module["SketchWorld.Params"]):
    """The Active Sketch scene (pipe, door with handle, package, surface) and its judge.

    Reads the arm's TRUE joints and gripper, moves what the gripper moves (the door follows a
    held handle), publishes the objects (for the simulated cameras and the 3-D view) and the
    verdict of the macro being played (``status.values``: grasp distance and angle, door angle,
    coverage, perimeter deviation, device error; ``stage`` = macro, ``message`` = events).
    ``randomize`` moves the objects about the nominal layout with the graph's seeded rng.
    With ``end_after`` set, the run ends (exit 0) once those macros have all succeeded, or with
    exit 1 at ``timeout_s`` (never in an attended run: ``ModuleContext.end_run``).

    Every macro played ends with one ``verdict`` (``stage`` = macro, ``message`` = what
    happened with the numbers, "grasped: 2.1 mm off the pipe axis, 0.4 deg off it" or "missed:
    gripper closed 11.0 mm off the pipe axis, ..."; ``values``: the figures and ``success`` 1/0;
    :mod:`umbra.modules.world.sketch_verdict`): a grasp macro when the gripper closes, placing a
    device when it opens, any other when the player reports the path ``done``. Logged, and
    listed in the summary (``macro_verdicts``).

    The console's *Stop* (a ``StopRun`` on the ``operator`` input; wire ``console.stop_run`` here)
    ends any run, attended or not, as a normal stop (exit 0), its verdict "stopped by the
    operator" with the macros that had succeeded; the summary's ``stopped`` says it ("" while
    no one stopped the run). :mod:`umbra.modules.world.operator_stop` holds the rule.
    """

    TYPE = "SketchWorld"

    class Params(ArmParams):
        tool_xyz: list[float] = param(
            [0.0, 0.0, 0.14], "tool point in the flange", unit="m", min_length=3, max_length=3
        )
        tool_rpy_deg: list[float] = param(
            [0.0, 0.0, 0.0], "tool frame in the flange", unit="deg", min_length=3, max_length=3
        )
        table_z: float = param(0.25, "table top above the arm's base", unit="m", ge=0, le=1.5)
        randomize: bool = param(False, "randomize the object poses (seeded)")
        objects_rate_hz: float = param(10.0, "how often the objects are published", gt=0, le=100)
        end_after: list[Macro] = param([], "end the run when these macros have all succeeded")
        timeout_s: float = param(120.0, "with end_after: fail the run after", unit="s", gt=0)

    joint_state = Input(JointState, feedback=True, doc="TRUE joint angles and gripper")
    path = Input(ToolPath, required=False, feedback=True, doc="the macro being played")
    vcr_state = Input(
        VcrState,
        required=False,
        feedback=True,
        doc="the player's state: a path played to its end (done) ends its macro",
    )
    operator = operator_input()
    objects = Output(SceneObjects, measured=True, doc="the true solids of the scene")
    status = Output(Status, measured=True, doc="the measures of the macro being played")
    arm_poses = Output(
        Poses,
        frame="base",
        measured=True,
        doc="TRUE T_base_link of the arm's links, tool and fingers, for the cameras to draw it",
    )
    verdict = Output(
        Verdict,
        events=True,
        measured=True,
        doc="one per macro played: succeeded or missed (outcome) with the numbers (stage = macro)",
    )

    def start(self) -> None:
        p = self.params
        self.table = p.table
        self.T_flange_tool = transform_from_xyz_rpy_deg(p.tool_xyz, p.tool_rpy_deg)
        scene = (
            SketchScene.random(self.context.rng, p.table_z)
            if p.randomize
            else SketchScene.nominal(p.table_z)
        )
        self.judge = SketchJudge(scene)
        self._macro: Macro | None = None  #: the macro being played (None before a path)
        self._verdicts: dict[Macro, dict[str, float]] = {}  #: each macro's figures at success
        self._next_objects = 0.0
        self._started: float | None = None
        self._last_key: tuple | None = None
        self._path_id = ""
        self._judged = True  #: the current macro has had its verdict (none before a path)
        self._macro_verdicts: list[dict[str, object]] = []
        self._arm: tuple[np.ndarray, float, float] | None = None  #: true q, gripper, stamp
        self._operator = OperatorStop()
        self._stopped = ""  #: the verdict of the operator's Stop ("" before it)

    def step(self, now: float) -> None:
        if self._started is None:
            self._started = now
        path = self.path.get(now)
        if path is not None and self.path.fresh and path.ok:
            self._macro, self._path_id, self._judged = path.macro, path.path_id, False
            self.judge.reset_measures()
        state = self.joint_state.get(now)
        if state is not None and self.joint_state.fresh:
            T = self.table.fk(np.asarray(state.position, dtype=float), self.T_flange_tool)
            self.judge.update(T, float(state.gripper))
            self._arm = (state.position, float(state.gripper), state.stamp)
        self._maybe_judge(now)
        if now >= self._next_objects:
            self._next_objects = now + 1.0 / self.params.objects_rate_hz
            v = self.judge.verdicts
            self.objects.send(
                self.judge.scene.message(values={"door_angle": self.judge.scene.door.angle})
            )
            self._report(now, v)
            if self._arm is not None:  # at the objects' rate: what the cameras draw
                q, gripper, stamp = self._arm
                matrices, children = arm_frames(self.table, q, self.T_flange_tool, gripper)
                self.arm_poses.send(
                    Poses(matrices=matrices, children=children, frame="base", stamp=stamp)
                )
        self._operator_command(now)  # before end_after: the person's Stop wins the tick
        self._maybe_end(now)

    def _operator_command(self, now: float) -> None:
        """The console's *Stop*: the run ends now as a normal stop (exit 0), whatever the macros'
        verdicts, the verdict naming the macros that had succeeded."""
        if not self._operator.requested(self.operator, now):
            return
        done = ", ".join(self._verdicts)
        self._stopped = f"{STOPPED_BY_OPERATOR}; " + (
            f"succeeded: {done}" if done else "no macro succeeded"
        )
        self.log.info(self._stopped)
        self.context.request_stop(self._stopped, 0)

    def _report(self, now: float, v) -> None:
        ok = self._macro is not None and v.success(self._macro)
        values = {
            "grasp_distance_mm": v.grasp_distance_m * 1e3,
            "grasp_angle_deg": float(np.degrees(v.grasp_angle_rad)),
            "door_angle_deg": float(np.degrees(self.judge.scene.door.angle)),
            "door_max_deg": float(np.degrees(v.door_max_rad)),
            "coverage": v.coverage,
            "perimeter_max_dev_mm": v.perimeter_max_dev_m * 1e3,
            "device_error_mm": v.device_error_m * 1e3,
            "success": float(ok),
        }
        if ok and self._macro is not None and self._macro not in self._verdicts:
            self._verdicts[self._macro] = {k: round(x, 3) for k, x in values.items()}
            self.log.info("SketchWorld: %s succeeded (%s)", self._macro, "; ".join(v.events))
        key = (self._macro, ok, len(v.events))
        if key != self._last_key:
            self._last_key = key
            self.status.send(
                Status(stage=self._macro or "idle", message="; ".join(v.events[-3:]), values=values)
            )

    def _maybe_judge(self, now: float) -> None:
        """The macro's verdict, once: at the gripper's close (grasps), its opening (placing a
        device) or the end of the path."""
        if self._judged or self._macro is None:
            return
        v = self.judge.verdicts
        vcr = self.vcr_state.get(now)
        ended = (
            (self._macro in GRASP_MACROS and v.closes > 0)
            or (self._macro in RELEASE_MACROS and v.opens > 0)
            or (vcr is not None and vcr.path_id == self._path_id and vcr.mode == VcrMode.DONE)
        )
        if not ended:
            return
        self._judged = True
        outcome, text, figures = macro_verdict(self._macro, v)
        figures = {k: round(float(x), 3) for k, x in figures.items()}
        self.verdict.send(Verdict(stage=self._macro, message=text, values=figures, outcome=outcome))
        entry: dict[str, object] = {
            "macro": self._macro,
            "path_id": self._path_id,
            "outcome": str(outcome),
            "verdict": text,
        }
        self._macro_verdicts.append(entry | figures)
        self.log.info("verdict of %s: %s", self._macro, text)

    def _maybe_end(self, now: float) -> None:
        wanted = self.params.end_after
        if not wanted:
            return
        if all(m in self._verdicts for m in wanted):
            self.context.end_run(f"macros succeeded: {', '.join(wanted)}", 0)
        elif self._started is not None and now - self._started > self.params.timeout_s:
            missing = [m for m in wanted if m not in self._verdicts]
            self.context.end_run(f"timeout: not succeeded: {', '.join(missing)}", 1)

    def summary(self) -> dict[str, object]:
        v = self.judge.verdicts
        return {
            "succeeded": list(self._verdicts),  # in the order they succeeded
            "verdicts": dict(self._verdicts),
            "door_angle_deg": float(np.degrees(self.judge.scene.door.angle)),
            "grasp_distance_mm": float(v.grasp_distance_m * 1e3),
            "events": list(v.events),
            "macro_verdicts": list(self._macro_verdicts),
            "stopped": self._stopped,
        }
