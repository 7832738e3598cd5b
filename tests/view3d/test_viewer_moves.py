"""A browser's viewer flight (ViewerMoves) against stand-ins for viser's server and client:
a browser that leaves mid-flight is sent nothing more."""

from __future__ import annotations

import threading
from contextlib import nullcontext
from types import SimpleNamespace

import numpy as np

from tests.poll import wait_for
from umbra.modules.view3d.geometry import viewer_pose_looking_at
from umbra.modules.view3d.viewer_moves import ViewerMoves


class _Camera:
    """A client's camera: every pose set on it is counted."""

    def __init__(self) -> None:
        self.sets = 0
        self.position = np.array([1.0, 0.0, 1.0])
        self.wxyz = np.array([1.0, 0.0, 0.0, 0.0])
        self.fov = 0.8
        self.look_at = np.zeros(3)
        self.up_direction = np.array([0.0, 0.0, 1.0])

    def __setattr__(self, name: str, value: object) -> None:
        if name in ("position", "look_at", "fov", "up_direction") and hasattr(self, "sets"):
            object.__setattr__(self, "sets", self.sets + 1)
        object.__setattr__(self, name, value)


def _moves(clients: dict[int, object]) -> ViewerMoves:
    moves = ViewerMoves()
    moves.server = SimpleNamespace(get_clients=lambda: dict(clients))
    moves.cameras, moves.snapshots = {}, {}
    moves.animation_s = 0.5
    moves._lock = threading.Lock()
    moves._generation, moves._following, moves._moving = {}, {}, set()
    return moves


def test_a_browser_that_leaves_mid_flight_is_sent_nothing_more() -> None:
    camera = _Camera()
    client = SimpleNamespace(client_id=7, camera=camera, atomic=nullcontext)
    clients: dict[int, object] = {7: client}
    moves = _moves(clients)
    goal = viewer_pose_looking_at([0.0, -1.0, 1.5], [0.0, 0.0, 0.0], 0.9)
    moves.animate_to(client, goal)  # type: ignore[arg-type]
    wait_for(lambda: camera.sets >= 8, 5.0, "the flight under way", interval_s=0.01)
    del clients[7]  # the browser left
    wait_for(lambda: not moves.moving(7), 5.0, "the flight over", interval_s=0.01)
    sent = camera.sets
    assert sent < 4 * 16  # it stopped before the whole flight (15 steps and the arrival)
    # and a browser still there is flown all the way
    other = SimpleNamespace(client_id=8, camera=_Camera(), atomic=nullcontext)
    clients[8] = other
    moves.animate_to(other, goal)  # type: ignore[arg-type]
    wait_for(lambda: not moves.moving(8), 5.0, "the other flight over", interval_s=0.01)
    np.testing.assert_allclose(other.camera.position, goal.position)
    assert camera.sets == sent
