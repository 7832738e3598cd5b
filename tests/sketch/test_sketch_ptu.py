"""Pan-tilt units: aiming by the Rochester solution, rate-limited slewing, the PTU module."""

from __future__ import annotations

import numpy as np
import pytest

from umbra.connectors.ptu_messages import PtuCommand
from umbra.modules.geometry.transforms import transform_from_xyz_rpy_deg
from umbra.modules.ptu.ptu_model import PtuGeometry, PtuLimitError, aim_in_base
from umbra.modules.ptu.ptu_module import Ptu
from umbra.modules.ptu.sim_ptu import SimPtu
from umbra.runtime.harness import ModuleHarness

#: unit 1.4 m up behind the arm, looking along base +x, 30 deg down (Z forward, Y down, X right)
T_BASE_PTU = transform_from_xyz_rpy_deg([-0.5, 0.25, 1.4], [-120, 0, -90])


def _axis_miss(geometry, T_base_ptu, pan, tilt, point):
    T = T_base_ptu @ geometry.T_ptu_mount(pan, tilt)
    d = np.asarray(point) - T[:3, 3]
    z = T[:3, 2]
    return np.linalg.norm(d - (d @ z) * z), d @ z


@pytest.mark.parametrize(
    "point", [[0.6, 0.0, 0.3], [0.4, -0.3, 0.25], [1.5, 0.8, 0.0], [2.0, -1.0, 0.6]]
)
def test_aim_puts_the_point_on_the_optic_axis(point):
    g = PtuGeometry()
    pan, tilt = aim_in_base(g, T_BASE_PTU, point)
    miss, depth = _axis_miss(g, T_BASE_PTU, pan, tilt, point)
    assert miss < 1e-9 and depth > 0.5


def test_aim_refuses_out_of_travel_points():
    with pytest.raises(PtuLimitError, match=r"tilt .* deg is outside the unit's travel"):
        aim_in_base(PtuGeometry(), T_BASE_PTU, [0.0, 0.25, 3.5])  # straight up


def test_slew_respects_rate_and_acceleration_and_settles():
    g = PtuGeometry(max_rate=1.0, max_accel=4.0)
    unit = SimPtu(g)
    unit.command(1.2, -0.5)
    dt, rates = 0.005, []
    for _ in range(600):
        unit.step(dt)
        rates.append(unit.rates.copy())
    rates = np.array(rates)
    assert np.allclose(unit.angles, [1.2, -0.5]) and not unit.moving
    assert np.abs(rates).max() <= 1.0 + 1e-9
    # acceleration within the limit; the last step that lands on the target may take two
    assert np.abs(np.diff(rates, axis=0)).max() <= 2 * 4.0 * dt + 1e-9
    assert np.sum(np.abs(np.diff(rates, axis=0)) > 4.0 * dt + 1e-9) <= 2


def test_ptu_module_aims_at_a_point_and_publishes_the_mount_pose():
    frames = {"base->ptu_left": T_BASE_PTU}
    params = {"ptu_frame": "ptu_left", "mount_name": "mount_left"}
    with ModuleHarness(Ptu, params, frames=frames) as h:
        h.push("command", PtuCommand(mode="point", point=np.array([0.6, 0.1, 0.3])))
        for _ in range(300):
            h.step(dt=0.01)
        state, pose = h.output("state"), h.output("mount_pose")
        assert not state.moving and state.status == "ok"
        g = PtuGeometry()
        T = pose.matrix
        d = np.array([0.6, 0.1, 0.3]) - T[:3, 3]
        assert np.linalg.norm(d - (d @ T[:3, 2]) * T[:3, 2]) < 1e-6
        h.push("command", PtuCommand(mode="angles", pan=0.0, tilt=1.5))
        h.step(dt=0.01)
        assert h.output("state").status.startswith("refused: tilt 85.9 deg is outside")
        assert g.max_rate == 1.0
