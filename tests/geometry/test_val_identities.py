"""The Rochester guide's VAL identities, each checked against the reconstruction in val.py."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from umbra.modules.geometry import val
from umbra.modules.geometry.transforms import rot_x, rot_y, rot_z, translation

LAB_X = np.array([1.0, 0.0, 0.0])
LAB_Y = np.array([0.0, 1.0, 0.0])
LAB_Z = np.array([0.0, 0.0, 1.0])


def test_t6_at_rest_has_the_axes_of_section_3_2():
    # "X axis pointing down (along LAB -Z), Y along LAB X, Z along LAB -Y".
    T6 = val.T_lab_t6_at_rest()
    np.testing.assert_allclose(T6[:3, 0], -LAB_Z, atol=1e-12)
    np.testing.assert_allclose(T6[:3, 1], LAB_X, atol=1e-12)
    np.testing.assert_allclose(T6[:3, 2], -LAB_Y, atol=1e-12)
    # It shares its origin with TOOL (section 3.2): the INIT location's X, Y, Z.
    np.testing.assert_allclose(T6[:3, 3], np.array(val.INIT_LOC_MM_DEG[:3]) / 1000, atol=1e-12)


def test_the_absolute_prefix_is_t6_at_rest():
    prefix = rot_z(np.radians(-90)) @ rot_y(np.radians(90))
    np.testing.assert_allclose(prefix[:3, :3], val.R_LAB_T6_AT_REST, atol=1e-12)


def test_nulltool_turns_t6_at_rest_parallel_to_lab():
    T6_rotation = val.R_LAB_T6_AT_REST
    nulltool = val.transform_from_relative_location_mm_deg(val.NULLTOOL_LOC_MM_DEG)
    np.testing.assert_allclose(T6_rotation @ nulltool[:3, :3], np.eye(3), atol=1e-12)
    np.testing.assert_allclose(nulltool[:3, 3], 0.0)


def test_init_location_describes_a_tool_parallel_to_lab():
    # Fig. 1: with JntAng = 0 and TOOL = NULLTOOL, Loc = (650, 190, 975, 90, -90, 0), and TOOL
    # is "simply a translation of LAB".
    T_lab_tool = val.transform_from_location_mm_deg(val.INIT_LOC_MM_DEG)
    np.testing.assert_allclose(T_lab_tool[:3, :3], np.eye(3), atol=1e-12)
    np.testing.assert_allclose(T_lab_tool[:3, 3], [0.650, 0.19013, 0.975], atol=1e-12)


def test_location_reported_for_t6_times_nulltool_is_the_init_location():
    T_lab_tool = val.T_lab_t6_at_rest() @ val.transform_from_relative_location_mm_deg(
        val.NULLTOOL_LOC_MM_DEG
    )
    np.testing.assert_allclose(
        val.location_mm_deg_from_transform(T_lab_tool), val.INIT_LOC_MM_DEG, atol=1e-9
    )


def test_flange_axes_at_rest_follow_section_3_3():
    T_lab_flange = val.T_lab_t6_at_rest() @ val.transform_from_relative_location_mm_deg(
        val.FLANGE_LOC_MM_DEG
    )
    np.testing.assert_allclose(T_lab_flange[:3, 2], LAB_Y, atol=1e-12)  # out of the head
    np.testing.assert_allclose(T_lab_flange[:3, 1], -LAB_Z, atol=1e-12)  # down
    np.testing.assert_allclose(T_lab_flange[:3, 0], LAB_X, atol=1e-12)  # right


def test_flange_equals_nulltool_times_a8():
    # Table 1: A8 = Rot_x(-90) when TOOL = NULLTOOL, identity when TOOL = FLANGE.
    nulltool = val.transform_from_relative_location_mm_deg(val.NULLTOOL_LOC_MM_DEG)
    flange = val.transform_from_relative_location_mm_deg(val.FLANGE_LOC_MM_DEG)
    np.testing.assert_allclose(nulltool @ rot_x(np.radians(-90)), flange, atol=1e-12)


def test_rotation_matches_the_d_matrix_of_section_9():
    rng = np.random.default_rng(1)
    for o, a, t in rng.uniform(-np.pi, np.pi, (20, 3)):
        so, co, sa, ca, st, ct = np.sin(o), np.cos(o), np.sin(a), np.cos(a), np.sin(t), np.cos(t)
        D = np.array(
            [
                [co * st - so * sa * ct, co * ct + so * sa * st, so * ca],
                [so * st + co * sa * ct, so * ct - co * sa * st, -co * ca],
                [-ca * ct, ca * st, -sa],
            ]
        )
        T = val.transform_from_location([0, 0, 0, o, a, t])
        np.testing.assert_allclose(T[:3, :3], D, atol=1e-12)
        # The section 9 identities.
        assert st * D[2, 0] + ct * D[2, 1] == pytest.approx(0.0, abs=1e-12)
        assert -sa == pytest.approx(D[2, 2], abs=1e-12)


def test_section_3_2_semantics_rotate_minus_o_about_x_then_a_about_y_then_t_about_z():
    o, a, t = np.radians([30.0, -20.0, 50.0])
    by_moves = rot_x(-o) @ rot_y(a) @ rot_z(t)
    np.testing.assert_allclose(val.oat_rotation(o, a, t), by_moves[:3, :3], atol=1e-12)


def test_xyz_is_the_tool_origin_in_lab():
    loc = [0.1, -0.2, 0.3, 0.4, 0.5, 0.6]
    T = val.transform_from_location(loc)
    np.testing.assert_allclose(T @ [0, 0, 0, 1], [0.1, -0.2, 0.3, 1.0])
    expected = translation(0.1, -0.2, 0.3)
    expected[:3, :3] = val.R_LAB_T6_AT_REST @ val.oat_rotation(0.4, 0.5, 0.6)
    np.testing.assert_allclose(T, expected, atol=1e-12)


def test_round_trip_over_random_locations():
    rng = np.random.default_rng(7)
    xyz = rng.uniform(-1000, 1000, (500, 3))
    o = rng.uniform(-180, 180, 500)
    a = rng.uniform(-90, 90, 500)
    t = rng.uniform(-180, 180, 500)
    for location in np.column_stack([xyz, o, a, t]):
        back = val.location_mm_deg_from_transform(val.transform_from_location_mm_deg(location))
        np.testing.assert_allclose(back[:3], location[:3], atol=1e-9)
        np.testing.assert_allclose(back[3:], location[3:], atol=1e-7)


def test_section_9_agrees_with_scipy_euler_extraction():
    rng = np.random.default_rng(3)
    for R in Rotation.random(100, random_state=rng).as_matrix():
        o, a, t = val.oat_from_rotation(R)
        minus_o, a_scipy, t_scipy = Rotation.from_matrix(R).as_euler("XYZ")
        np.testing.assert_allclose([o, a, t], [-minus_o, a_scipy, t_scipy], atol=1e-9)


@pytest.mark.parametrize("a_deg", [90.0, -90.0])
def test_gimbal_lock_is_deterministic_and_exact(a_deg):
    rng = np.random.default_rng(11)
    for o, t in rng.uniform(-170, 170, (50, 2)):
        T = val.transform_from_location_mm_deg([10, 20, 30, o, a_deg, t])
        back = val.location_mm_deg_from_transform(T)
        assert back[5] == 0.0  # T is set to zero
        assert back[4] == pytest.approx(a_deg, abs=1e-9)
        # O absorbs the free rotation: O - T for A = +90, O + T for A = -90 (modulo 360).
        expected_o = o - t if a_deg > 0 else o + t
        assert np.cos(np.radians(back[3] - expected_o)) == pytest.approx(1.0, abs=1e-12)
        np.testing.assert_allclose(val.transform_from_location_mm_deg(back), T, atol=1e-12)
        assert (val.location_mm_deg_from_transform(T) == back).all()


def test_near_gimbal_round_trip_reproduces_the_transform():
    for a_deg in (90 - 1e-7, -90 + 1e-7, 89.999):
        T = val.transform_from_location_mm_deg([0, 0, 0, 33, a_deg, -71])
        back = val.location_mm_deg_from_transform(T)
        np.testing.assert_allclose(val.transform_from_location_mm_deg(back), T, atol=1e-9)


def test_relative_round_trip_of_the_guide_tools():
    for loc in (val.NULLTOOL_LOC_MM_DEG, val.FLANGE_LOC_MM_DEG, (5, -6, 7, 12, 34, 56)):
        T = val.transform_from_relative_location_mm_deg(loc)
        back = val.relative_location_mm_deg_from_transform(T)
        np.testing.assert_allclose(val.transform_from_relative_location_mm_deg(back), T, atol=1e-12)


def test_bad_location_is_rejected():
    with pytest.raises(val.ValLocationError, match="6 finite numbers"):
        val.transform_from_location_mm_deg([1, 2, 3])
    with pytest.raises(val.ValLocationError, match="6 finite numbers"):
        val.transform_from_location_mm_deg([1, 2, 3, 4, np.nan, 6])
