"""Value types of the VISCA zoom client: settings, readings, counters, link status and the
reply predicates the client and its device thread share."""

from __future__ import annotations

import enum
from dataclasses import dataclass

from umbra.connectors.errors import UserError
from umbra.connectors.messages import DEVICE_OK
from umbra.modules.calib.visca import protocol as vp


class LinkStatus(enum.Enum):
    """Health of the link to the camera; the value is the prefix of the status text."""

    OK = DEVICE_OK
    STARTING = "starting"
    NO_REPLY = "no_reply"
    GARBLED = "garbled"
    CAMERA_ERROR = "camera_error"
    PORT_ERROR = "port_error"


@dataclass(frozen=True)
class ViscaSettings:
    """How to reach the camera and how patient to be. Times in seconds."""

    port: str
    address: int = 1
    baudrate: int = 9600
    poll_period_s: float = 0.1
    reply_timeout_s: float = 0.3
    retries: int = 2
    completion_timeout_s: float = 6.0
    """Longest a zoom may take from ACK to completion (full travel is ~2.4 s on an FCB)."""
    retry_backoff_s: float = 0.5
    """Wait before repeating a failed initialisation or a refused zoom command."""
    reinit_after_failures: int = 3
    arrival_tolerance_raw: int = 16
    """A polled position this close to the commanded one counts as arrived (lost completion)."""
    read_slice_s: float = 0.02

    def __post_init__(self) -> None:
        problems = []
        if not 1 <= self.address <= 7:
            problems.append(f"address must be 1..7, got {self.address}")
        if self.retries < 0:
            problems.append(f"retries must be >= 0, got {self.retries}")
        for name in ("poll_period_s", "reply_timeout_s", "completion_timeout_s", "read_slice_s"):
            if not getattr(self, name) > 0:
                problems.append(f"{name} must be > 0, got {getattr(self, name)}")
        if problems:
            raise UserError("VISCA settings: " + "; ".join(problems))


@dataclass(frozen=True)
class ZoomReading:
    """Latest knowledge of the camera's zoom.

    ``zoom`` normalized 0 (wide) .. 1 (optical tele), NaN until the first position reply; ``raw``
    the FCB's zoom position (-1 until known); ``moving`` while a zoom command runs or the polled
    position changes; ``target`` the last requested normalized zoom (None if none);
    ``position_time`` ``time.monotonic()`` [s] of the last position reply (NaN if none).
    """

    zoom: float
    raw: int
    moving: bool
    target: float | None
    status: str
    link: LinkStatus
    ready: bool
    position_time: float

    @property
    def ok(self) -> bool:
        return self.link is LinkStatus.OK


@dataclass
class ViscaCounters:
    """What happened on the wire since start."""

    packets_sent: int = 0
    replies: int = 0
    timeouts: int = 0
    retries: int = 0
    garbled: int = 0
    """Runs of bytes thrown away by the splitter plus framed packets that did not decode."""
    camera_errors: int = 0
    zoom_commands: int = 0
    zoom_moves: int = 0
    """Tele/wide/stop commands sent (continuous zoom)."""
    zoom_completions: int = 0
    power_ons: int = 0
    """Times the camera was found in standby at start and powered on."""
    polls: int = 0
    initialisations: int = 0
    foreign_replies: int = 0
    end_stops: int = 0
    """Zoom stops sent by ``stop()`` because a zoom this client started could still be running."""
    end_stop_failures: int = 0
    """Of those, the ones the camera did not acknowledge (it may still be zooming)."""


@dataclass
class Problem:
    link: LinkStatus
    detail: str


# Precedence of problems in the status text: the link first, then the camera's answers.
PRECEDENCE = (
    LinkStatus.PORT_ERROR,
    LinkStatus.NO_REPLY,
    LinkStatus.GARBLED,
    LinkStatus.CAMERA_ERROR,
    LinkStatus.STARTING,
)


def status_text(problems: dict[str, Problem]) -> tuple[LinkStatus, str]:
    for link in PRECEDENCE:
        for problem in problems.values():
            if problem.link is link:
                return link, f"{link.value}: {problem.detail}"
    return LinkStatus.OK, LinkStatus.OK.value


def is_position_reply(reply: vp.Reply, address: int) -> bool:
    return (
        isinstance(reply, vp.Completion)
        and reply.address == address
        and reply.socket == 0
        and len(reply.payload) == 4
        and all(b <= 0x0F for b in reply.payload)
    )


def is_empty_completion(reply: vp.Reply, address: int) -> bool:
    return (
        isinstance(reply, vp.Completion)
        and reply.address == address
        and reply.socket == 0
        and not reply.payload
    )


def is_power_reply(reply: vp.Reply, address: int) -> bool:
    """A CAM_PowerInq reply ``y0 50 02/03 FF`` from camera ``address``."""
    return (
        isinstance(reply, vp.Completion)
        and reply.address == address
        and reply.socket == 0
        and reply.payload in (b"\x02", b"\x03")
    )


class RequestFailedError(Exception):
    """A request got no good answer after all its tries (internal to the device thread)."""

    def __init__(self, link: LinkStatus, detail: str) -> None:
        super().__init__(detail)
        self.link = link
        self.detail = detail
