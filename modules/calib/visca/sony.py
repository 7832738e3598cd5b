"""SONY: the zoom of a Sony FCB block camera over VISCA, as a module (the SMART SONY module).

Takes the operator's (or the targeting system's) zoom request, normalized 0 (full wide) .. 1
(full optical tele), and publishes the camera's zoom as :class:`ZoomState` each time a position
poll comes back, so CamCalib can interpolate the calibration at the zoom the camera really has.
With ``port: sim`` the module serves a simulated FCB on a pseudo-terminal and talks to it through
the same serial client, so graphs run without hardware.

The serial port is served by the client's device thread; ``step`` only hands over the latest
request and reads the latest reading, and never blocks. The camera runs on wall time whatever the
graph's clock: under ``--clock sim`` the zoom still takes its real travel time.
"""

from __future__ import annotations

import math
import re
from typing import Any, Literal

from pydantic import field_validator

from umbra.connectors import Input, Module, Output, Parameters, param
from umbra.connectors.messages import Scalar, ZoomState
from umbra.modules.calib.visca.client import ViscaSettings, ViscaZoomClient, ZoomReading
from umbra.modules.calib.visca.commands import MAX_ZOOM_SPEED, ZoomDirection
from umbra.modules.calib.visca.sim_camera import Fault, SimFcbCamera

#: A serial device the module may open: an absolute device path (``/dev/ttyUSB0``,
#: ``/dev/serial/by-id/usb-FTDI_...-if00-port0``) or a Windows ``COM3``; no spaces, no shell or
#: YAML characters.
SERIAL_PORT_RE = re.compile(r"^(/[A-Za-z0-9._+:@=,-]+)+$|^(\\\\\.\\)?COM[0-9]{1,3}$")


def serial_port_problem(port: str) -> str:
    """Why ``port`` cannot name the camera's serial port; empty when it can (``sim`` or a device
    path; whether the device exists is known only on the machine that runs the module)."""
    if port == "sim" or SERIAL_PORT_RE.match(port):
        return ""
    return (
        f"port {port!r} is not a serial device: expected an absolute device path such as "
        "/dev/ttyUSB0 (letters, digits and . _ + : @ = , - between slashes), COM3, or `sim`"
    )


class Sony(Module["Sony.Params"]):
    """Sony FCB zoom camera over VISCA (serial, or `sim` on a pty): zoom commands, position polls.

    ``zoom_command`` sets a position; ``zoom_hold`` drives the zoom like a rocker held down
    (tele or wide at a speed until released: a hold value of 0, or no hold sample for
    ``hold_timeout_s``, stops it); the latest of the two wins.
    ``zoom.status`` is "ok" or "<problem>: <detail>" with problem one of starting, no_reply,
    garbled, camera_error, port_error; ``zoom.zoom`` is NaN and ``zoom.raw`` -1 until the camera
    has reported a position. Device trouble never stops the run; a port that cannot be opened at
    start is a user error. At the run's end (however it ends) a zoom the module started and that
    may still run is stopped (CAM_Zoom stop). Give it a graph rate of about twice
    ``poll_rate_hz``: it publishes one sample per poll and runs on new commands too.
    """

    TYPE = "SONY"

    class Params(Parameters):
        port: str = param("sim", "serial device (/dev/ttyUSB0) or `sim` for a simulated FCB")

        @field_validator("port")
        @classmethod
        def _port(cls, value: str) -> str:
            problem = serial_port_problem(value)
            if problem:
                raise ValueError(problem)
            return value

        address: int = param(1, "VISCA address of the camera on the chain", ge=1, le=7)
        baudrate: Literal[9600, 19200, 38400] = param(9600, "serial speed (8N1)", unit="baud")
        poll_rate_hz: float = param(10.0, "zoom position polls per second", unit="Hz", gt=0, le=50)
        reply_timeout_s: float = param(0.3, "wait for each reply", unit="s", gt=0, le=10)
        retries: int = param(2, "resends of a request that got no good reply", ge=0, le=10)
        completion_timeout_s: float = param(
            6.0, "longest zoom travel before completion is given up", unit="s", gt=0
        )
        retry_backoff_s: float = param(
            0.5, "pause before repeating a failed set-up or refused zoom", unit="s", gt=0
        )
        start_timeout_s: float = param(
            2.0,
            "how long start waits for the camera to answer (it never fails on this)",
            unit="s",
            ge=0,
        )
        sim_full_range_s: float = param(
            2.4, "simulated camera: wide-to-tele travel time", unit="s", gt=0
        )
        sim_fault: Literal["none", "garble", "silent", "error"] = param(
            "none", "simulated camera: misbehave from the start (for tests and demos)"
        )
        hold_timeout_s: float = param(
            0.3, "zoom_hold dead-man: stop when no hold sample came for this long", unit="s", gt=0
        )

    zoom_command = Input(
        Scalar,
        trigger=True,
        required=False,
        doc="requested zoom, normalized 0 (wide)..1 (tele); clamped",
    )
    zoom_hold = Input(
        Scalar,
        trigger=True,
        required=False,
        doc="zoom rocker held: >0 tele, <0 wide, |v| the speed (1 fastest), 0 stop; send it "
        "repeatedly while held: no sample for hold_timeout_s stops the zoom (dead-man)",
    )
    zoom = Output(
        ZoomState, measured=True, doc="camera zoom at each position poll, with link status"
    )

    def start(self) -> None:
        p = self.params
        self._sim: SimFcbCamera | None = None
        self._last_key: tuple[Any, ...] | None = None
        self._published = 0
        self._ignored_commands = 0
        self._holding_since: float | None = None  # graph time of the last hold sample
        self._deadman_stops = 0
        port = p.port
        if port == "sim":
            self._sim = SimFcbCamera(full_range_s=p.sim_full_range_s, seed=0)
            port = self._sim.start()
            self._sim.inject(Fault(p.sim_fault))
        settings = ViscaSettings(
            port=port,
            address=p.address,
            baudrate=p.baudrate,
            poll_period_s=1.0 / p.poll_rate_hz,
            reply_timeout_s=p.reply_timeout_s,
            retries=p.retries,
            completion_timeout_s=p.completion_timeout_s,
            retry_backoff_s=p.retry_backoff_s,
        )
        self._client = ViscaZoomClient(settings)
        try:
            self._client.start()
        except Exception:
            self._stop_sim()
            raise
        if not self._client.wait_ready(p.start_timeout_s):
            self.log.warning(
                "camera not ready after %.1f s: %s", p.start_timeout_s, self._client.latest().status
            )

    def step(self, now: float) -> None:
        if self.zoom_command.fresh:
            command = self.zoom_command.get(now)
            if command is not None:
                if math.isfinite(command.value):
                    self._client.zoom_to(command.value)
                else:
                    self._ignored_commands += 1
                self._holding_since = None
        self._obey_hold(now)
        reading = self._client.latest()
        key = (reading.position_time, reading.raw, reading.moving, reading.status)
        if key == self._last_key:
            return
        self._last_key = key
        self._published += 1
        self.zoom.send(self._zoom_state(reading))

    def _obey_hold(self, now: float) -> None:
        """Start, change or stop a held zoom; stop it when its samples stop coming (dead-man)."""
        if self.zoom_hold.fresh:
            sample = self.zoom_hold.get(now)
            if sample is not None and math.isfinite(sample.value):
                move = hold_move(sample.value)
                if move is None:
                    self._client.zoom_stop()
                    self._holding_since = None
                else:
                    self._client.zoom_hold(*move)
                    self._holding_since = now
                return
            if sample is not None:
                self._ignored_commands += 1
        if self._holding_since is not None and now - self._holding_since > (
            self.params.hold_timeout_s
        ):
            self._client.zoom_stop()
            self._holding_since = None
            self._deadman_stops += 1

    def _zoom_state(self, reading: ZoomReading) -> ZoomState:
        # On the real clock (time.monotonic) the sample is stamped when the position arrived.
        real = self.context.clock == "real" and math.isfinite(reading.position_time)
        return ZoomState(
            stamp=reading.position_time if real else 0.0,
            zoom=reading.zoom,
            raw=reading.raw,
            moving=reading.moving,
            status=reading.status,
        )

    def stop(self) -> None:
        client = getattr(self, "_client", None)
        if client is not None:
            client.stop()
        self._stop_sim()

    def _stop_sim(self) -> None:
        if getattr(self, "_sim", None) is not None:
            assert self._sim is not None
            self._sim.stop()
            self._sim = None

    def summary(self) -> dict[str, Any]:
        client = getattr(self, "_client", None)
        if client is None:
            return {}
        c = client.counters
        reading = client.latest()
        return {
            "status": reading.status,
            "zoom": reading.zoom,
            "published": self._published,
            "polls": c.polls,
            "zoom_commands": c.zoom_commands,
            "zoom_completions": c.zoom_completions,
            "timeouts": c.timeouts,
            "retries": c.retries,
            "garbled": c.garbled,
            "camera_errors": c.camera_errors,
            "ignored_commands": self._ignored_commands,
            "zoom_moves": c.zoom_moves,
            "deadman_stops": self._deadman_stops,
            "end_zoom_stops": c.end_stops,
            "end_zoom_stop_failures": c.end_stop_failures,
        }


def hold_move(value: float) -> tuple[ZoomDirection, int] | None:
    """The continuous zoom a ``zoom_hold`` value asks for: direction and variable speed 0..7
    (|value| in (0, 1], 1 fastest, clamped), or None for 0 (stop)."""
    if value == 0:
        return None
    steps = MAX_ZOOM_SPEED + 1
    speed = min(MAX_ZOOM_SPEED, max(0, math.ceil(min(abs(value), 1.0) * steps) - 1))
    return (ZoomDirection.TELE if value > 0 else ZoomDirection.WIDE), speed
