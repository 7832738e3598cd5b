"""WOLVERINE_KIN: tool twist to joint rates (damped least squares) and the tool pose."""

from __future__ import annotations

import numpy as np

from umbra.connectors import Input, Output, from_param, param
from umbra.connectors.limits import MAX_COMMAND_AGE_S
from umbra.connectors.messages import JointRates, JointState, Pose, Poses, Status, Twist
from umbra.connectors.module import Module
from umbra.modules.arm.arm_params import ArmParams
from umbra.modules.arm.dls import DLSSettings, solve_dls
from umbra.modules.arm.jacobian import (
    jacobian_and_pose_at_frames,
    manipulability,
    tool_twist_in_base,
)
from umbra.modules.geometry.transforms import transform_from_xyz_rpy_deg


class WolverineKin(Module["WolverineKin.Params"]):
    """Resolved-rate kinematics of a DH arm (default: Puma 560).

    Each new tool twist (tool point, tool-frame coordinates) is re-expressed in the base frame
    and solved for joint rates with damped least squares at the latest joint state: damping rises
    only near a singularity, and rates over the arm's limits are scaled down together (direction
    kept). Also publishes the tool pose (``T_base_tool``), the pose of every DH link frame in the
    base frame (``T_base_link1`` ... ``T_base_flange``, in chain order: a recording or a live
    viewer shows them as the chain base → link1 → … → flange, each link in the one before) and a
    status with the manipulability and the near-singularity / near-limit flags.
    Without a recent joint state it sends zero rates.
    """

    TYPE = "WOLVERINE_KIN"

    class Params(ArmParams):
        base_frame: str = param("base", "frame of the arm's base (DH frame 0)")
        tool_frame: str = param("tool", "frame of the tool point (flange + tool transform)")
        flange_frame: str = param("flange", "frame of the last DH link (the flange)")
        link_frame_prefix: str = param(
            "link", "DH frames 1 .. n-1 are named PREFIX1 .. PREFIX<n-1> in `link_poses`"
        )
        tool_xyz: list[float] = param(
            [0.0, 0.0, 0.0],
            "tool point in the flange frame",
            unit="m",
            min_length=3,
            max_length=3,
        )
        tool_rpy_deg: list[float] = param(
            [0.0, 0.0, 0.0],
            "tool frame orientation in the flange frame",
            unit="deg",
            min_length=3,
            max_length=3,
        )
        dls_eps: float = param(0.04, "singular value where damping starts (J units)", gt=0)
        dls_lambda_max: float = param(0.04, "damping at a singularity (J units)", gt=0)
        limit_margin_deg: float = param(5.0, "flag joints this close to a limit", unit="deg", ge=0)
        max_state_age: float = param(
            0.1, "oldest joint state used", unit="s", gt=0, le=MAX_COMMAND_AGE_S, safety=True
        )

        @property
        def tool_pose_frames(self) -> str:
            """``base->tool``: the frames ``tool_pose`` relates (parent->child)."""
            return f"{self.base_frame}->{self.tool_frame}"

    tool_twist = Input(Twist, frame=from_param("tool_frame"), trigger=True, doc="tool twist")
    joint_state = Input(
        JointState, joints=from_param("joint_names"), feedback=True, doc="measured joint angles"
    )
    joint_rates = Output(JointRates, joints=from_param("joint_names"), doc="joint rate command")
    tool_pose = Output(
        Pose, frame=from_param("tool_pose_frames"), doc="T_base_tool at the joint state used"
    )
    link_poses = Output(
        Poses,
        frame=from_param("base_frame"),
        doc="T_base_link of each DH frame 1 .. n in chain order (link1 ... flange) at the joint "
        "state used",
    )
    status = Output(Status, doc="manipulability, flags, why rates are zero (on change)")

    def start(self) -> None:
        p = self.params
        self.table = p.table
        self.T_flange_tool = transform_from_xyz_rpy_deg(p.tool_xyz, p.tool_rpy_deg)
        self.settings = DLSSettings(
            eps=p.dls_eps, lambda_max=p.dls_lambda_max, limit_margin=np.radians(p.limit_margin_deg)
        )
        self._zero = np.zeros(self.table.n)
        n = self.table.n
        self.link_names = (
            *(f"{p.link_frame_prefix}{i}" for i in range(1, n)),
            p.flange_frame,
        )
        self._last_flags: tuple[str, bool, bool] | None = None
        self._zeroed = 0
        self._singular = 0

    def step(self, now: float) -> None:
        twist = self.tool_twist.get(now)
        if twist is None or not self.tool_twist.fresh:
            return
        state = self.joint_state.get(now)
        problem = self._state_problem(now, state)
        if not problem and twist.frame != self.params.tool_frame:
            problem = f"tool twist in frame `{twist.frame}`, expected `{self.params.tool_frame}`"
        if problem:
            self._zeroed += 1
            self._send(JointRates(names=self.table.names, rates=self._zero), problem, None)
            return
        assert state is not None
        q = np.asarray(state.position, dtype=float)
        T_base_links = self.table.frames(q)
        J, T_base_tool = jacobian_and_pose_at_frames(self.table, T_base_links, self.T_flange_tool)
        result = solve_dls(
            J,
            tool_twist_in_base(T_base_tool, twist.vector),
            q,
            self.table.q_min,
            self.table.q_max,
            self.table.qd_max,
            self.settings,
        )
        self._singular += result.near_singularity
        rates = JointRates(
            names=self.table.names,
            rates=result.rates,
            near_singularity=result.near_singularity,
            near_limit=result.near_limit,
        )
        self.tool_pose.send(
            Pose(matrix=T_base_tool, parent=self.params.base_frame, child=self.params.tool_frame)
        )
        self.link_poses.send(
            Poses(matrices=T_base_links[1:], children=self.link_names, frame=self.params.base_frame)
        )
        self._send(rates, "", J, result.scale, result.sigma_min)

    def _state_problem(self, now: float, state: JointState | None) -> str:
        if state is None:
            return "no joint state yet"
        age = self.joint_state.age(now)
        if age > self.params.max_state_age:
            return f"joint state is {age:.3f} s old (max {self.params.max_state_age:.3f} s)"
        if tuple(state.names) != self.table.names:
            return f"joint state names {list(state.names)} differ from {list(self.table.names)}"
        position = np.asarray(state.position, dtype=float)
        if position.shape != (self.table.n,) or not np.all(np.isfinite(position)):
            return f"joint state has unknown angles: {position.tolist()}"
        return ""

    def _send(
        self,
        rates: JointRates,
        problem: str,
        J: np.ndarray | None,
        scale: float = 1.0,
        sigma_min: float = 0.0,
    ) -> None:
        self.joint_rates.send(rates)
        flags = (problem, rates.near_singularity, rates.near_limit)
        if flags == self._last_flags:
            return
        self._last_flags = flags
        values = {"scale": scale, "sigma_min": sigma_min}
        if J is not None:
            values["manipulability"] = manipulability(J)
        words = [w for w, on in (("near singularity", flags[1]), ("near limit", flags[2])) if on]
        self.status.send(
            Status(
                stage="zero" if problem else "tracking",
                message=problem or (", ".join(words) if words else "ok"),
                reason=problem,
                values=values,
            )
        )

    def summary(self) -> dict[str, int]:
        return {"zeroed_ticks": self._zeroed, "near_singularity_ticks": self._singular}
