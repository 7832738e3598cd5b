"""Puma 560 forward kinematics, Jacobian and manipulability."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from umbra.modules.arm.dh import DHError, DHJoint, DHTable, puma560
from umbra.modules.arm.jacobian import jacobian, jacobian_and_pose, manipulability
from umbra.modules.geometry.transforms import rot_x, rot_z, translation

PUMA = puma560()


def random_q(rng: np.random.Generator, table: DHTable = PUMA) -> np.ndarray:
    return rng.uniform(np.maximum(table.q_min, -np.pi), np.minimum(table.q_max, np.pi))


def test_zero_pose_is_the_sum_of_the_dh_offsets():
    # At q = 0 every rotation cancels (alpha 90, 0, -90, 90, -90, 0): R = I, and the flange sits
    # at x = a2 + a3, y = -d3, z = d1 + d4 (Corke's RTB documents (0.4521, -0.15, 0.4318) for a
    # base at the shoulder, i.e. without d1 = 26.45 in = 0.67183 m).
    T = PUMA.fk(np.zeros(6))
    np.testing.assert_allclose(T[:3, :3], np.eye(3), atol=1e-12)
    np.testing.assert_allclose(T[:3, 3], [0.4318 + 0.0203, -0.15005, 0.67183 + 0.4318], atol=1e-5)


def test_shoulder_height_is_26_45_inches():
    # Corke's PUMA 560 survey: the shoulder axis stands 26.45 in above the mounting surface; one
    # inch is 0.0254 m exactly, so d1 = 0.67183 m (0.6718 is 0.03 mm low on every z).
    assert PUMA.joints[0].d == pytest.approx(0.67183, abs=1e-9)
    assert PUMA.fk(np.zeros(6))[2, 3] - 0.4318 == pytest.approx(26.45 * 0.0254, abs=1e-12)


def test_shoulder_up_pose_computed_by_hand():
    # q2 = +90 deg swings the upper arm straight up: elbow at height d1 + a2, the forearm offset
    # a3 adds height, d4 runs along -x of the base; wrist axes: x = +z, y = +y, z = -x.
    T = PUMA.fk([0, np.pi / 2, 0, 0, 0, 0])
    np.testing.assert_allclose(T[:3, 3], [-0.4318, -0.15005, 0.67183 + 0.4318 + 0.0203], atol=1e-5)
    np.testing.assert_allclose(T[:3, :3], [[0, 0, -1], [0, 1, 0], [1, 0, 0]], atol=1e-12)


def test_nominal_pose_matches_corkes_documented_value():
    # RTB: fkine(qn), qn = (0, 45, 180, 0, 45, 0) deg -> t = (0.5963, -0.1501, 0.6575), R = Ry(90).
    T = PUMA.fk(np.radians([0, 45, 180, 0, 45, 0]))
    np.testing.assert_allclose(T[:3, 3], [0.5963, -0.1501, 0.6575], atol=1e-4)
    np.testing.assert_allclose(T[:3, :3], [[0, 0, 1], [0, 1, 0], [-1, 0, 0]], atol=1e-12)


def test_waist_rotation_rotates_the_whole_pose_about_base_z():
    rng = np.random.default_rng(0)
    for _ in range(20):
        q = random_q(rng)
        q1 = rng.uniform(-1, 1)
        turned = q.copy()
        turned[0] += q1
        np.testing.assert_allclose(PUMA.fk(turned), rot_z(q1) @ PUMA.fk(q), atol=1e-12)


def test_fk_matches_an_explicit_product_of_paul_matrices():
    rng = np.random.default_rng(1)
    q = random_q(rng)
    T = np.eye(4)
    for joint, qi in zip(PUMA.joints, q, strict=True):
        T = T @ rot_z(qi) @ translation(0, 0, joint.d) @ translation(joint.a, 0, 0)
        T = T @ rot_x(joint.alpha)
    np.testing.assert_allclose(PUMA.fk(q), T, atol=1e-12)


def test_tool_transform_is_applied_after_the_flange():
    tool = translation(0.0, 0.0, 0.1)
    q = np.radians([10, 20, -30, 40, 50, 60])
    np.testing.assert_allclose(PUMA.fk(q, tool), PUMA.fk(q) @ tool, atol=1e-12)


def numeric_jacobian(table, q, tool=None, h=1e-6):
    J = np.zeros((6, table.n))
    for i in range(table.n):
        dq = np.zeros(table.n)
        dq[i] = h
        Tp, Tm = table.fk(q + dq, tool), table.fk(q - dq, tool)
        J[:3, i] = (Tp[:3, 3] - Tm[:3, 3]) / (2 * h)
        # Angular velocity in the base frame: (R(q+h) R(q-h)^T) as a rotation vector / 2h.
        J[3:, i] = Rotation.from_matrix(Tp[:3, :3] @ Tm[:3, :3].T).as_rotvec() / (2 * h)
    return J


@pytest.mark.parametrize("with_tool", [False, True])
def test_jacobian_matches_finite_differences_at_100_configurations(with_tool):
    rng = np.random.default_rng(2)
    tool = translation(0.02, -0.01, 0.15) @ rot_x(0.3) if with_tool else None
    for _ in range(100):
        q = random_q(rng)
        np.testing.assert_allclose(
            jacobian(PUMA, q, tool), numeric_jacobian(PUMA, q, tool), atol=1e-6
        )


def test_prismatic_joint_column_and_fk():
    table = DHTable(
        joints=(
            DHJoint("base", d=0.3, alpha=np.pi / 2),
            DHJoint("slide", kind="prismatic", theta=np.pi / 2, alpha=-np.pi / 2, q_min=0, q_max=1),
            DHJoint("wrist", d=0.1),
        ),
        name="rpr",
    )
    rng = np.random.default_rng(3)
    for _ in range(20):
        q = np.array([rng.uniform(-3, 3), rng.uniform(0, 1), rng.uniform(-3, 3)])
        np.testing.assert_allclose(jacobian(table, q), numeric_jacobian(table, q), atol=1e-6)
    J = jacobian(table, [0.0, 0.5, 0.0])
    np.testing.assert_allclose(J[3:, 1], 0.0)  # a prismatic joint adds no rotation
    assert np.linalg.norm(J[:3, 1]) == pytest.approx(1.0)


def test_manipulability_is_zero_at_the_wrist_singularity_and_positive_elsewhere():
    q = np.radians([0, 45, 180, 0, 45, 0])
    J, _ = jacobian_and_pose(PUMA, q)
    w = manipulability(J)
    assert w == pytest.approx(np.sqrt(np.linalg.det(J @ J.T)), rel=1e-9)
    assert w > 1e-3
    q_singular = q.copy()
    q_singular[4] = 0.0  # q5 = 0 aligns the axes of joints 4 and 6
    assert manipulability(jacobian(PUMA, q_singular)) < 1e-12


def test_bad_tables_and_joint_vectors_are_rejected():
    with pytest.raises(DHError, match="unique"):
        DHTable(joints=(DHJoint("a"), DHJoint("a")))
    with pytest.raises(DHError, match="revolute or prismatic"):
        DHJoint("a", kind="spherical")
    with pytest.raises(DHError, match="q_min"):
        DHJoint("a", q_min=1.0, q_max=0.0)
    with pytest.raises(DHError, match="6 joints, got 5"):
        PUMA.fk(np.zeros(5))
    assert PUMA.names == ("j1", "j2", "j3", "j4", "j5", "j6")
