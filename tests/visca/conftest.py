"""Fixtures for the VISCA tests: a simulated FCB camera on a real pty and a client on it."""

from __future__ import annotations

from collections.abc import Callable, Iterator

import pytest
import serial

from umbra.modules.calib.visca.client import ViscaSettings, ViscaZoomClient
from umbra.modules.calib.visca.sim_camera import SimFcbCamera

#: Short timeouts so fault tests take a fraction of a second each.
FAST = {
    "poll_period_s": 0.05,
    "reply_timeout_s": 0.1,
    "retries": 1,
    "retry_backoff_s": 0.1,
    "reinit_after_failures": 2,
}


@pytest.fixture
def wire(sim: SimFcbCamera) -> Iterator[serial.Serial]:
    """pyserial on the simulated camera's pty, for raw bytes."""
    port = serial.Serial(sim.path, 9600, timeout=2.0)
    yield port
    port.close()


@pytest.fixture
def sim() -> Iterator[SimFcbCamera]:
    camera = SimFcbCamera(full_range_s=1.0, seed=7)
    camera.start()
    yield camera
    camera.stop()


@pytest.fixture
def client_on() -> Iterator[Callable[..., ViscaZoomClient]]:
    clients: list[ViscaZoomClient] = []

    def make(camera: SimFcbCamera, **overrides: object) -> ViscaZoomClient:
        settings = ViscaSettings(port=camera.path, **{**FAST, **overrides})  # type: ignore[arg-type]
        client = ViscaZoomClient(settings)
        client.start()
        clients.append(client)
        return client

    yield make
    for client in clients:
        client.stop()
