"""Rochester head chain: CamPos from (phi, theta), its inverse, and aiming a camera."""

from __future__ import annotations

import numpy as np
import pytest

from umbra.modules.geometry import rochester_head as head
from umbra.modules.geometry.transforms import invert_transform, transform_points


def test_campos_at_zero_angles_is_the_sum_of_the_guide_offsets():
    for side, eye in (("left", -0.0127), ("right", 0.1524)):
        T = head.T_flange_campos(0.0, 0.0, side)
        np.testing.assert_allclose(T[:3, :3], np.eye(3), atol=1e-15)
        # A9..A14 translations: (eye, NECK + ALT, AZ) = (eye, -0.1492 - 0.0651, 0.0349).
        np.testing.assert_allclose(T[:3, 3], [eye, -0.2143, 0.0349], atol=1e-12)


def test_altitude_tilts_up_and_azimuth_turns_right():
    optic_axis_up = head.T_flange_campos(0.2, 0.0, "left")[:3, 2]
    assert optic_axis_up[1] < 0  # FLANGE -Y is up
    optic_axis_right = head.T_flange_campos(0.0, 0.2, "left")[:3, 2]
    assert optic_axis_right[0] > 0


def test_section_8_recovers_the_angles():
    rng = np.random.default_rng(0)
    for phi, theta in rng.uniform(-1.2, 1.2, (100, 2)):
        for side in ("left", "right"):
            T = head.T_flange_campos(phi, theta, side)
            assert head.head_angles_from_campos(T) == pytest.approx((phi, theta), abs=1e-12)


def test_aiming_puts_the_point_on_the_optic_axis():
    rng = np.random.default_rng(1)
    for _ in range(200):
        side = "left" if rng.random() < 0.5 else "right"
        # Points in front of the head, up to ~40 degrees off axis, 0.4 .. 2 m away.
        point = np.array([rng.uniform(-0.6, 0.6), rng.uniform(-0.6, 0.6), rng.uniform(0.8, 2.0)])
        phi, theta = head.aim_camera_at_point(point, side)
        T_flange_camera = head.T_flange_campos(phi, theta, side)
        in_camera = transform_points(invert_transform(T_flange_camera), point)
        assert in_camera[2] > 0  # in front of the camera
        np.testing.assert_allclose(in_camera[:2], 0.0, atol=1e-12)


def test_aiming_straight_ahead_of_the_pitch_axis_needs_only_the_offset_tilt():
    # A point straight ahead of the left camera's axis at the height of the optic axis at rest.
    camaxis = head.T_flange_camaxis("left")[:3, 3]
    point = camaxis + np.array([0.0, -0.0651, 1.5])
    phi, theta = head.aim_camera_at_point(point, "left")
    assert phi == pytest.approx(0.0, abs=1e-12)
    assert theta == pytest.approx(0.0, abs=1e-12)


def test_aiming_at_a_point_too_close_fails_clearly():
    camaxis = head.T_flange_camaxis("right")[:3, 3]
    with pytest.raises(head.AimError, match="altitude axis"):
        head.aim_camera_at_point(camaxis + np.array([0.0, 0.01, 0.01]), "right")
    with pytest.raises(ValueError, match="left' or 'right"):
        head.T_flange_campos(0, 0, "middle")
