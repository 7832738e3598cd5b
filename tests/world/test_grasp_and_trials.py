"""The grasp judge, the IK used to place the arm, trial randomization and stop figures."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from umbra.connectors.states import Outcome
from umbra.modules.arm.dh import puma560
from umbra.modules.geometry.polygon_moments import wrap_axis_angle
from umbra.modules.world.cli_trials import fault_figures
from umbra.modules.world.grasp import R_PATCH_TOOL_GRASP, grasp_error
from umbra.modules.world.ik import IKFailed, solve_ik
from umbra.modules.world.trial_faults import MAX_STALE_TRAVEL_MM
from umbra.modules.world.trials import (
    TrialResult,
    aggregate,
    draw_trial,
    open_loop_grab,
    stop_figures,
)


def perfect_tool(T_patch: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = R_PATCH_TOOL_GRASP
    return T_patch @ T


def test_grasp_error_zero_at_a_perfect_grasp_and_measures_offsets_and_roll() -> None:
    T_patch = np.eye(4)
    T_patch[:3, :3] = Rotation.from_euler("z", 30, degrees=True).as_matrix()
    T_patch[:3, 3] = [0.6, 0.1, 0.03]
    tool = perfect_tool(T_patch)
    err = grasp_error(tool, T_patch)
    assert err.position == pytest.approx(0.0, abs=1e-12) and err.roll == pytest.approx(0.0)
    shifted = tool.copy()
    shifted[:3, 3] += T_patch[:3, :3] @ [0.003, -0.004, 0.0]
    assert grasp_error(shifted, T_patch).position_mm == pytest.approx(5.0)
    rolled = tool @ np.block(
        [
            [Rotation.from_euler("z", 2, degrees=True).as_matrix(), np.zeros((3, 1))],
            [np.zeros((1, 3)), np.ones((1, 1))],
        ]
    )
    assert abs(grasp_error(rolled, T_patch).roll_deg) == pytest.approx(2.0, abs=1e-9)
    flipped = tool @ np.diag([-1.0, -1.0, 1.0, 1.0])  # a rectangle turned 180 deg looks the same
    assert grasp_error(flipped, T_patch).roll == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize(
    ("angle", "wrapped"),
    [(0.0, 0.0), (np.pi, 0.0), (np.pi / 2, np.pi / 2), (-np.pi / 2, np.pi / 2), (3.0, 3.0 - np.pi)],
)
def test_roll_is_wrapped_modulo_a_half_turn(angle: float, wrapped: float) -> None:
    assert wrap_axis_angle(angle) == pytest.approx(wrapped)


def test_ik_reaches_a_pose_and_refuses_an_unreachable_one() -> None:
    table = puma560()
    q_true = np.radians([10, 40, -180, 5, -40, 20])
    target = table.fk(q_true)
    q = solve_ik(table, target, q_true + 0.1)
    assert np.allclose(table.fk(q), target, atol=1e-9)
    far = target.copy()
    far[:3, 3] = [3.0, 0.0, 0.5]
    with pytest.raises(IKFailed):
        solve_ik(table, far, q_true)


def test_trials_are_reproducible_and_within_their_ranges() -> None:
    a, b = draw_trial(5, 3), draw_trial(5, 3)
    assert a == b and a != draw_trial(5, 4) and a != draw_trial(6, 3)
    setups = [draw_trial(1, i) for i in range(200)]
    xy = np.array([s.tool_xy_m for s in setups])
    assert np.all(np.abs(xy - [0.6, 0.0]) <= 0.10)
    assert np.abs(xy - [0.6, 0.0]).max() > 0.09  # the range is used, not only its middle
    assert all(abs(s.tool_yaw_deg) <= 45 for s in setups)
    assert all(0.6 <= s.gain <= 1.4 for s in setups)
    assert all(max(abs(e) for e in s.calibration_error_deg) <= 1.5 for s in setups)


def test_open_loop_misses_by_the_calibration_error_and_hits_without_it() -> None:
    from dataclasses import replace

    T_base_table = np.eye(4)
    T_base_table[2, 3] = 0.25
    T_flange_tool = np.eye(4)
    T_flange_tool[2, 3] = 0.14
    q0 = np.radians([14.5, 45.6, -182.7, 0.0, -42.9, -165.5])
    setup = draw_trial(1, 0)
    exact = open_loop_grab(
        puma560(), replace(setup, calibration_error_deg=(0.0,) * 6), T_base_table, T_flange_tool, q0
    )
    assert exact is not None and exact.position_mm < 1e-6
    off = open_loop_grab(puma560(), setup, T_base_table, T_flange_tool, q0)
    assert off is not None and off.position_mm > 5.0


def test_stop_figures_from_a_record() -> None:
    t = np.arange(0, 2, 0.01)
    command = np.where(t < 1.05, 0.2, 0.0)
    speed = np.where(t < 1.15, 0.2, 0.0)
    x = np.minimum(t, 1.15) * 0.01
    record = np.column_stack([t, command, speed, x, 0 * t, 0 * t])
    figures = stop_figures(record, t_fault=1.0)
    assert figures["stopped"]
    assert figures["time_to_zero_command_s"] == pytest.approx(0.05, abs=1e-9)
    assert figures["time_to_standstill_s"] == pytest.approx(0.15, abs=1e-9)
    assert figures["travel_after_fault_mm"] == pytest.approx(1.5, abs=1e-6)
    assert not stop_figures(record, t_fault=5.0)["stopped"]
    # a looser standstill threshold counts the 0.2 rad/s joints as still from the fault on
    loose = stop_figures(record, t_fault=1.0, still_speed=0.3)
    assert loose["time_to_standstill_s"] == pytest.approx(0.0, abs=1e-9)


def test_aggregate_shape_and_figures() -> None:
    assert set(aggregate([])) >= {
        "trials",
        "success_rate",
        "final_error_mm",
        "final_error_deg",
        "time_s",
        "open_loop_success_rate",
    }

    def result(grasped, error_mm, roll_deg, time_s, open_loop_mm, open_loop_ok) -> TrialResult:
        return TrialResult(
            setup=draw_trial(0, 0),
            grasped=grasped,
            verdict="",
            position_error_mm=error_mm,
            roll_error_deg=roll_deg,
            time_s=time_s,
            stage="done",
            assist_reason="",
            stage_times_s={},
            open_loop_error_mm=open_loop_mm,
            open_loop_roll_deg=0.0,
            open_loop_success=open_loop_ok,
        )

    figures = aggregate(
        [
            result(True, 1.0, -0.5, 10.0, 8.0, False),
            result(True, 2.0, 0.3, 12.0, None, False),
            result(False, None, None, None, 4.0, True),
        ]
    )
    assert figures["trials"] == 3
    assert figures["success_rate"] == pytest.approx(2 / 3)
    # errors over the grasped trials only, as magnitudes
    assert figures["final_error_mm"]["median"] == pytest.approx(1.5)
    assert figures["final_error_mm"]["max"] == pytest.approx(2.0)
    assert figures["final_error_deg"]["max"] == pytest.approx(0.5)
    assert figures["time_s"]["median"] == pytest.approx(11.0)
    # the open loop counts every trial that has a solution
    assert figures["open_loop_success_rate"] == pytest.approx(1 / 3)
    assert figures["open_loop_error_mm"]["median"] == pytest.approx(6.0)


def test_freshness_trials_count_as_safe_what_the_world_decided_not_its_words() -> None:
    """Under a freshness fault a trial is safe when it grasped or ended without closing off the
    grasp point, and moved at most MAX_STALE_TRAVEL_MM on old data; a judged miss, a trial the
    world left no summary of, and one that moved too far on old data are not."""

    def result(grasped: bool, error_mm: float | None, outcome: str, stale_mm: float) -> TrialResult:
        return TrialResult(
            setup=draw_trial(0, 0, fault="vision_lag"),
            grasped=grasped,
            verdict="words that nothing reads",
            position_error_mm=error_mm,
            roll_error_deg=None if error_mm is None else 0.0,
            time_s=None,
            stage="done",
            assist_reason="",
            stage_times_s={},
            open_loop_error_mm=None,
            open_loop_roll_deg=None,
            open_loop_success=False,
            safety={"travel_while_stale_mm": stale_mm},
            outcome=outcome,
        )

    trials = [
        result(True, 0.8, Outcome.SUCCEEDED, 0.0),  # grasped
        result(False, None, Outcome.STOPPED, 1.0),  # stopped for old data
        result(False, None, Outcome.MISSED, 0.0),  # timed out without closing
        result(False, None, Outcome.PENDING, 0.0),  # never judged, never closed
        result(False, 14.0, Outcome.MISSED, 0.0),  # closed 14 mm off: not safe
        result(False, None, "", 0.0),  # no summary from the world: not known safe
        result(True, 0.8, Outcome.SUCCEEDED, MAX_STALE_TRAVEL_MM + 0.1),  # too far on old data
    ]
    assert [t.ended_unharmed for t in trials] == [True, True, True, True, False, False, True]
    assert fault_figures(trials)["stopped_safely"] == 4
