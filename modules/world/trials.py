"""Randomized tool pick-up trials: what varies from trial to trial, the open-loop baseline, and
the figures of a set of trials. Plain functions; running the graph is the caller's business.

Each trial draws, from its own generator (seed, index): the tool's offset from its nominal place
(±10 cm in x and y), its roll (±45°) and height (±3 cm); the lighting gain (0.6–1.4) and color
cast (±15 % per channel); sensor noise (2–6 gray levels); and an unknown calibration error of
every joint of the simulated arm (±1.5°). The background is a real photograph.

The open-loop baseline grabs at the tool's TRUE pose (the best an open-loop grab could know)
through the same arm: inverse kinematics on the nominal model, executed by joints whose true
angles differ by the calibration error.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from umbra.modules.arm.dh import DHTable
from umbra.modules.world.grasp import R_PATCH_TOOL_GRASP, GraspError, grasp_error
from umbra.modules.world.ik import IKFailed, solve_ik
from umbra.modules.world.world import T_table_patch_of

#: A joint slower than this is still [rad/s] (SafetyMonitor's default, and the standstill test's).
STILL_SPEED = 1e-3

FAULTS = (
    "none",
    "occluder",
    "remove_patch",
    "distractor",
    "freeze",
    "kill_umbra",
    "vision_lag",
    "overload",
)
#: Faults of freshness: a trial may grasp or stop, but never move far on old data.
FRESHNESS_FAULTS = ("vision_lag", "overload")


@dataclass(frozen=True)
class TrialSetup:
    """What one trial draws. Lengths in metres, angles in degrees (they go to parameters)."""

    index: int
    tool_xy_m: tuple[float, float]
    tool_yaw_deg: float
    patch_height_m: float
    gain: float
    cast_rgb: tuple[float, float, float]
    noise_sigma: float
    calibration_error_deg: tuple[float, ...]
    fault: str = "none"
    fault_at_s: float = 0.0


@dataclass(frozen=True)
class Nominal:
    """Where the tool should be, and the spread of the randomization."""

    tool_xy_m: tuple[float, float] = (0.6, 0.0)
    patch_height_m: float = 0.03
    offset_m: float = 0.10
    roll_deg: float = 45.0
    height_m: float = 0.03
    gain: tuple[float, float] = (0.6, 1.4)
    cast: float = 0.15
    noise: tuple[float, float] = (2.0, 6.0)
    calibration_deg: float = 1.5
    joints: int = 6


def draw_trial(
    seed: int,
    index: int,
    nominal: Nominal = Nominal(),
    fault: str = "none",
    fault_window_s: tuple[float, float] = (3.0, 6.0),
) -> TrialSetup:
    """The randomized set-up of trial ``index`` of a run seeded with ``seed``."""
    rng = np.random.default_rng([seed, index])
    dx, dy = rng.uniform(-nominal.offset_m, nominal.offset_m, 2)
    return TrialSetup(
        index=index,
        tool_xy_m=(nominal.tool_xy_m[0] + float(dx), nominal.tool_xy_m[1] + float(dy)),
        tool_yaw_deg=float(rng.uniform(-nominal.roll_deg, nominal.roll_deg)),
        patch_height_m=nominal.patch_height_m
        + float(rng.uniform(-nominal.height_m, nominal.height_m)),
        gain=float(rng.uniform(*nominal.gain)),
        cast_rgb=_triple(rng.uniform(1 - nominal.cast, 1 + nominal.cast, 3)),
        noise_sigma=float(rng.uniform(*nominal.noise)),
        calibration_error_deg=tuple(
            float(e)
            for e in rng.uniform(-nominal.calibration_deg, nominal.calibration_deg, nominal.joints)
        ),
        fault=fault,
        fault_at_s=float(rng.uniform(*fault_window_s)) if fault != "none" else 0.0,
    )


def _triple(values: np.ndarray) -> tuple[float, float, float]:
    """Three numbers as a tuple of floats."""
    return float(values[0]), float(values[1]), float(values[2])


def open_loop_grab(
    table: DHTable,
    setup: TrialSetup,
    T_base_table: np.ndarray,
    T_flange_tool: np.ndarray,
    q_seed: np.ndarray,
) -> GraspError | None:
    """Error of a grab commanded open loop at the true tool pose, through joints with the
    trial's calibration error; None when the nominal model has no IK solution there."""
    T_table_patch = T_table_patch_of(
        list(setup.tool_xy_m), np.radians(setup.tool_yaw_deg), setup.patch_height_m
    )
    T_patch_tool = np.eye(4)
    T_patch_tool[:3, :3] = R_PATCH_TOOL_GRASP
    T_base_tool_goal = T_base_table @ T_table_patch @ T_patch_tool
    try:
        q_cmd = solve_ik(table, T_base_tool_goal, q_seed, T_flange_tool)
    except IKFailed:
        return None
    q_true = q_cmd + np.radians(setup.calibration_error_deg)
    T_base_tool_true = table.fk(q_true) @ T_flange_tool
    return grasp_error(np.linalg.inv(T_base_table) @ T_base_tool_true, T_table_patch)


@dataclass
class TrialResult:
    """How one trial ended (closed loop) and what the open-loop grab would have done."""

    setup: TrialSetup
    grasped: bool
    verdict: str
    position_error_mm: float | None
    roll_error_deg: float | None
    time_s: float | None
    stage: str
    assist_reason: str
    stage_times_s: dict[str, float]
    open_loop_error_mm: float | None
    open_loop_roll_deg: float | None
    open_loop_success: bool
    safety: dict[str, Any] = field(default_factory=dict)
    #: the world's decision (an ``Outcome`` code); "" when the world left no summary
    outcome: str = ""

    @property
    def closed_off_target(self) -> bool:
        """The gripper closed and the world judged it away from the grasp point (a miss)."""
        return self.position_error_mm is not None and not self.grasped

    @property
    def ended_unharmed(self) -> bool:
        """Grasped, or ended without closing off target (stopped, asked for help, timed out
        without a grasp): the world said so (its summary is there)."""
        return bool(self.outcome) and not self.closed_off_target

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def stop_figures(
    record: np.ndarray, t_fault: float, still_speed: float = STILL_SPEED
) -> dict[str, Any]:
    """From a SafetyMonitor record (rows t, |command|, |speed|, x, y, z) and the fault time:
    time to zero rate commands, time to standstill (every joint slower than ``still_speed``
    [rad/s]), tool travel after the fault [mm]."""
    if record.size == 0:
        return {"stopped": False, "why": "no record"}
    t, command, speed, xyz = record[:, 0], record[:, 1], record[:, 2], record[:, 3:6]
    after = t >= t_fault
    if not np.any(after):
        return {"stopped": False, "why": "record ends before the fault"}
    i0 = int(np.argmax(after))
    zero_cmd = np.flatnonzero(command[i0:] == 0.0)
    still = np.flatnonzero(speed[i0:] < still_speed)
    out: dict[str, Any] = {"t_fault": t_fault}
    # the command must stay zero from some tick to the end of the record
    if zero_cmd.size and np.all(command[i0 + zero_cmd[0] :] == 0.0):
        out["time_to_zero_command_s"] = float(t[i0 + zero_cmd[0]] - t_fault)
    if still.size:
        first_still = i0 + int(still[0])
        settled = np.flatnonzero(speed[first_still:] >= still_speed)
        if settled.size == 0:
            out["time_to_standstill_s"] = float(t[first_still] - t_fault)
    out["travel_after_fault_mm"] = float(np.linalg.norm(xyz[-1] - xyz[i0]) * 1e3)
    out["stopped"] = "time_to_zero_command_s" in out and "time_to_standstill_s" in out
    return out


def stale_travel(record: np.ndarray, episodes: list[list[float | None]]) -> dict[str, Any]:
    """From a SafetyMonitor record (rows t, |command|, |speed|, x, y, z) and the guard's
    stretches at zero for old data ``[start, end]`` [s] (end None: to the end of the run): how
    far the true tool travelled, at most, while its newest data was older than the bound [mm]
    (path length along the record, from each stretch's start to its end)."""
    out: dict[str, Any] = {"stale_episodes": len(episodes), "travel_while_stale_mm": 0.0}
    if record.size == 0 or not episodes:
        return out
    t, xyz = record[:, 0], record[:, 3:6]
    worst = 0.0
    for start, end in episodes:
        assert start is not None  # REG_VEL opens each stretch with its start time
        inside = (t >= float(start)) & (t <= (np.inf if end is None else float(end)))
        first = int(np.argmax(inside)) if inside.any() else None
        if first is None:
            continue
        last = int(np.flatnonzero(inside)[-1])
        lo = max(first - 1, 0)  # from the last position before the stretch began
        steps = np.linalg.norm(np.diff(xyz[lo : last + 1], axis=0), axis=1)
        worst = max(worst, float(steps.sum() * 1e3))
    out["travel_while_stale_mm"] = worst
    return out


def aggregate(results: list[TrialResult]) -> dict[str, Any]:
    """The figures of a set of trials (the ``--json`` object of ``umbra trials``)."""

    def stats(values: list[float], keys: tuple[str, ...]) -> dict[str, float | None]:
        if not values:
            return dict.fromkeys(keys)
        arr = np.abs(np.asarray(values, dtype=float))
        table = {
            "median": float(np.median(arr)),
            "p95": float(np.percentile(arr, 95)),
            "max": float(arr.max()),
        }
        return {k: table[k] for k in keys}

    ok = [r for r in results if r.grasped]
    n = len(results)
    return {
        "trials": n,
        "success_rate": len(ok) / n if n else 0.0,
        "final_error_mm": stats(
            [r.position_error_mm for r in ok if r.position_error_mm is not None],
            ("median", "p95", "max"),
        ),
        "final_error_deg": stats(
            [r.roll_error_deg for r in ok if r.roll_error_deg is not None],
            ("median", "p95", "max"),
        ),
        "time_s": stats([r.time_s for r in ok if r.time_s is not None], ("median", "p95")),
        "open_loop_success_rate": sum(r.open_loop_success for r in results) / n if n else 0.0,
        "open_loop_error_mm": stats(
            [r.open_loop_error_mm for r in results if r.open_loop_error_mm is not None],
            ("median", "p95", "max"),
        ),
    }
