"""World: the simulated plant of the tool pick-up — where the tool really is, where the camera
really is, and whether the grasp succeeded.

It knows the truth the controller never sees: the true joint angles (from the simulated joints,
calibration error included), hence the true camera pose, and the true pose of the tool's patch on
its tray. It publishes both for the simulated camera, and when the gripper closes it judges the
grasp against the truth and ends the run: exit 0 when grasped within tolerance, 1 otherwise.
Its ``status`` says ``running`` until then and the verdict after, re-sent every
``status_period_s`` so a page that joins late reads it. In an attended run
(``ModuleContext.attended``) the verdict is published and logged but the run goes on until the
person stops it: no end after an assistance request, no timeout. The person stops it with the
console's *Stop* (a ``StopRun`` on the ``operator`` input, any run): the run ends as a normal stop,
its verdict "stopped by the operator" (after the grasp's verdict when one was judged), exit 0
unless the grasp was judged missed.

Frames: ``base`` (robot base), ``flange``, ``tool`` (gripper centre point; the graph's static
frame ``flange->tool``), ``camera`` (``flange->camera`` through the static frames), ``table``
(the table top, z up; the graph's static frame ``base->table``), ``patch`` (centre of the patch
on the tool's top face, x along its long side). Poses are published in the table frame, the
simulated camera's world.
"""

from __future__ import annotations

import numpy as np

from umbra.connectors import Input, Module, Output, UserError, param
from umbra.connectors.messages import JointState, Pose, Poses
from umbra.connectors.reasons import Code
from umbra.connectors.states import GuardState, Outcome, Presence, ServoState, Verdict
from umbra.modules.arm.arm_params import ArmParams
from umbra.modules.arm.arm_solids import TRUE_PREFIX, arm_frames
from umbra.modules.world.grasp import grasp_error
from umbra.modules.world.operator_stop import STOPPED_BY_OPERATOR, OperatorStop, operator_input


class WorldState(Code):
    """The world's state, the ``stage`` of its status: running until the grasp is judged, then
    grasped, missed (a miss, or no grasp: the run failed, exit 1) or stopped (by the operator
    before a grasp, exit 0)."""

    RUNNING = "running"
    GRASPED = "grasped"
    MISSED = "missed"
    STOPPED = "stopped"


def T_table_patch_of(
    tool_xy_m: list[float], tool_yaw_rad: float, patch_height_m: float
) -> np.ndarray:
    """Pose of the patch on the table: at (x, y), ``patch_height_m`` up, turned about z."""
    c, s = np.cos(tool_yaw_rad), np.sin(tool_yaw_rad)
    T = np.eye(4)
    T[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    T[:3, 3] = [tool_xy_m[0], tool_xy_m[1], patch_height_m]
    return T


class WorldParams(ArmParams):
    """Parameters of the simulated world (the arm's DH table comes from ArmParams)."""

    def required_frames(self) -> list[tuple[str, str]]:
        """The camera and tool on the flange, and the table in the base frame."""
        return [("flange", "camera"), ("flange", "tool"), ("table", "base")]

    tool_xy_m: list[float] = param(
        [0.6, 0.0],
        "tool (patch centre) x, y in the table frame",
        unit="m",
        min_length=2,
        max_length=2,
    )
    tool_yaw_deg: float = param(
        0.0, "tool rotation about the vertical", unit="deg", ge=-180, le=180
    )
    patch_height_m: float = param(0.03, "patch top face above the table", unit="m", ge=0, le=0.3)
    position_tolerance_mm: float = param(
        2.0, "grasped when the tool point is this close", unit="mm", gt=0
    )
    roll_tolerance_deg: float = param(
        1.0, "grasped when the roll error is this small", unit="deg", gt=0
    )
    timeout_s: float = param(60.0, "end the run as failed when no grasp by then", unit="s", gt=0)
    end_run: bool = param(True, "end the run when the grasp is judged")
    status_period_s: float = param(
        1.0,
        "re-send the status (running, or the verdict) this often, for pages that join late",
        unit="s",
        gt=0,
        le=60,
    )
    end_after_stop_s: float = param(
        1.5,
        "after an operator-assistance request or a lost vision process, end the run this "
        "much later (the arm has stopped)",
        unit="s",
        gt=0,
    )


TRUE_FLANGE, TRUE_TOOL = TRUE_PREFIX + "flange", TRUE_PREFIX + "tool"


class SimWorld(Module[WorldParams]):
    """The simulated plant: true camera and patch poses out, grasp judged when the gripper shuts."""

    TYPE = "World"
    Params = WorldParams

    joint_state = Input(JointState, feedback=True, doc="TRUE joint angles and gripper of the arm")
    servo_status = Input(
        ServoState,
        required=False,
        feedback=True,
        doc="the grab's stage (vsServo): ends the run after an assist request",
    )
    presence = Input(
        Presence,
        required=False,
        feedback=True,
        doc="the operator console's presence: once a person took control, an assist request "
        "no longer ends the run (the person answers it)",
    )
    guard = Input(
        GuardState,
        required=False,
        feedback=True,
        doc="the safety register's status (REG_VEL): a run that ends while it holds the arm for "
        "old data says 'stopped: data too old'",
    )
    operator = operator_input()
    camera_pose = Output(Pose, frame="table->camera", measured=True, doc="true T_table_camera")
    patch_pose = Output(Pose, frame="table->patch", measured=True, doc="true T_table_patch")
    status = Output(
        Verdict,
        measured=True,
        doc="world state: running, grasped, missed or stopped, with errors and the outcome",
    )
    arm_poses = Output(
        Poses,
        frame="table",
        measured=True,
        doc="TRUE T_table_link of the arm's links, tool and fingers (by the gripper's opening), "
        "for the simulated camera to draw the arm",
    )

    def start(self) -> None:
        p = self.params
        frames = self.context.frames
        try:
            self.T_flange_camera = frames.lookup("flange", "camera")
            self.T_flange_tool = frames.lookup("flange", "tool")
            self.T_table_base = frames.lookup("table", "base")
        except KeyError as exc:
            raise UserError(
                f"World `{self.name}` needs the static frames base->table, "
                f"flange->tool and tool->camera in the graph: {exc}"
            ) from None
        self.T_table_patch = T_table_patch_of(
            p.tool_xy_m, np.radians(p.tool_yaw_deg), p.patch_height_m
        )
        self.t0: float | None = None
        self.result: dict[str, object] = {
            "grasped": False,
            "verdict": "no grasp attempted",
            "outcome": str(Outcome.PENDING),
        }
        self._closing_seen = False
        self._judged = False
        self._stopped_since: float | None = None
        self._stop_reason = ""
        self._state = WorldState.RUNNING
        self._status = Verdict(stage=self._state, message="no grasp yet")
        self._status_due = -np.inf
        self._operator = OperatorStop()

    def step(self, now: float) -> None:
        if self.t0 is None:
            self.t0 = now
        state = self.joint_state.get(now)
        self.patch_pose.send(Pose(matrix=self.T_table_patch, parent="table", child="patch"))
        self._operator_command(now)
        self._send_status(now)
        if state is None:
            return
        matrices, children = arm_frames(
            self.params.table, state.position, self.T_flange_tool, state.gripper, self.T_table_base
        )
        T_table_flange = matrices[children.index(TRUE_FLANGE)]  # one forward kinematics a tick
        T_table_tool = matrices[children.index(TRUE_TOOL)]
        self.arm_poses.send(
            Poses(matrices=matrices, children=children, frame="table", stamp=state.stamp)
        )
        self.camera_pose.send(
            Pose(
                matrix=T_table_flange @ self.T_flange_camera,
                parent="table",
                child="camera",
                stamp=state.stamp,
            )
        )
        if self._judged:
            return
        if state.gripper < 0.99:
            self._closing_seen = True
        if self._closing_seen and state.gripper <= 0.0:
            self._judge(now, T_table_tool)
        elif self.context.attended:
            return  # the person answers requests and decides when to stop
        elif self._servo_stopped(now):
            verdict = f"stopped without a grasp: {self._stop_reason}"
            self._finish(now, False, verdict, outcome=Outcome.STOPPED)
        elif now - self.t0 > self.params.timeout_s:
            verdict = self._why_not(f"no grasp within {self.params.timeout_s:g} s")
            held = Outcome.STOPPED if self._held_for_old_data() else Outcome.MISSED
            self._finish(now, False, verdict, outcome=held)

    def _operator_command(self, now: float) -> None:
        """The console's *Stop*: the run ends now as a normal stop, its verdict 'stopped by the
        operator' (after the grasp's verdict, when one was judged: exit 1 only for a miss)."""
        if not self._operator.requested(self.operator, now):
            return
        if self._judged:
            verdict = f"{self.result['verdict']}; {STOPPED_BY_OPERATOR}"
            grasped = bool(self.result["grasped"])
            self._finish(now, grasped, verdict, self._state, self._status.outcome)
        else:
            verdict = f"{STOPPED_BY_OPERATOR} before a grasp"
            self._finish(now, False, verdict, WorldState.STOPPED, Outcome.STOPPED)

    def _why_not(self, missed: str) -> str:
        """The verdict of a run without a grasp: 'stopped: data too old' first when the guard
        holds the arm for old data at the end (the control path could not stay fresh)."""
        guard = self.guard.value
        if guard is not None and self._held_for_old_data():
            return f"stopped: data too old ({guard.reason}); {missed}"
        return missed

    def _held_for_old_data(self) -> bool:
        """The guard holds the arm at zero for old data now."""
        guard = self.guard.value
        return guard is not None and not guard.passing and guard.stale

    def _servo_stopped(self, now: float) -> bool:
        """True ``end_after_stop_s`` after the grab asked for help or its process vanished."""
        status = self.servo_status.get(now)
        person = self.presence.value
        if person is not None and person.acted:
            self._stopped_since = None  # a person at the console answers for the grab
            return False
        if self._stopped_since is None:
            if status is not None and status.assist:
                self._stopped_since = now
                self._stop_reason = f"operator assistance requested ({status.reason})"
            elif status is not None and self.servo_status.link_gone:
                self._stopped_since = now
                self._stop_reason = "the vision process is gone"
        return (
            self._stopped_since is not None
            and now - self._stopped_since >= self.params.end_after_stop_s
        )

    def _judge(self, now: float, T_table_tool: np.ndarray) -> None:
        err = grasp_error(T_table_tool, self.T_table_patch)
        p = self.params
        ok = (
            err.position_mm <= p.position_tolerance_mm and abs(err.roll_deg) <= p.roll_tolerance_deg
        )
        self.result.update(
            {
                "position_error_mm": round(err.position_mm, 4),
                "roll_error_deg": round(err.roll_deg, 4),
                "tilt_deg": round(float(np.degrees(err.tilt)), 4),
                "offset_patch_mm": [round(v * 1e3, 3) for v in err.offset_patch],
            }
        )
        verdict = (
            f"grasped: tool point {err.position_mm:.2f} mm from the grasp point, roll "
            f"error {err.roll_deg:.2f} deg"
            if ok
            else f"missed: tool point {err.position_mm:.2f} mm from the grasp point, roll "
            f"error {err.roll_deg:.2f} deg (tolerance {p.position_tolerance_mm:g} mm, "
            f"{p.roll_tolerance_deg:g} deg)"
        )
        self._finish(now, ok, verdict)

    def outcome_at_duration(self) -> tuple[int, str] | None:
        """A run that reaches its duration before the grasp was judged has failed (exit 1)."""
        if self.params.end_run and not self._judged:
            return 1, self._why_not("no grasp before the run's duration ended")
        return None

    def _finish(
        self,
        now: float,
        grasped: bool,
        verdict: str,
        state: WorldState | None = None,
        outcome: Outcome | None = None,
    ) -> None:
        """Publish and log the verdict; end the run unless it is attended (a person ends an
        attended run with *Stop*, which ends any run), exit 1 when the state is missed.
        ``state``: None says grasped or missed; ``outcome``: None says succeeded or missed."""
        self._judged = True
        self.result.update(
            {
                "grasped": grasped,
                "verdict": verdict,
            }
        )
        self.result.setdefault("time_s", round(now - (self.t0 if self.t0 is not None else now), 3))
        values = {k: float(v) for k, v in self.result.items() if isinstance(v, int | float)}
        if outcome is None:
            outcome = Outcome.SUCCEEDED if grasped else Outcome.MISSED
        self.result["outcome"] = str(outcome)
        if state is None:
            state = WorldState.GRASPED if grasped else WorldState.MISSED
        self._state = state
        self._status = Verdict(
            stage=state,
            message=verdict,
            values=values,
            outcome=outcome,
        )
        self._status_due = -np.inf
        self._send_status(now)
        self.log.info(verdict)
        code = 1 if state is WorldState.MISSED else 0
        if self._operator.stopped:
            self.context.request_stop(verdict, code)
        elif self.params.end_run:
            self.context.end_run(verdict, code)

    def _send_status(self, now: float) -> None:
        """The status (running, or the verdict once judged) when due."""
        if now < self._status_due:
            return
        self._status_due = now + self.params.status_period_s
        self.status.send(self._status)

    def summary(self) -> dict[str, object]:
        return dict(self.result)
