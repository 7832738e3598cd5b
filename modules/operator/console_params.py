"""The operator console's parameters, with their units and bounds."""

from __future__ import annotations

from typing import Annotated

from pydantic import Field, field_validator

from umbra.connectors import param
from umbra.connectors.access.hosts import MAX_TCP_PORT
from umbra.modules.arm.arm_params import ArmParams

#: How long [s] a page waits without hearing from the run before it drops its socket (a
#: half-open connection) or, with the socket closed, says the run may be gone. The console
#: sends it in its welcome; its state comes at least twice in that time (``state_rate_hz``).
PAGE_SILENT_S = 5.0

#: A side of the patch drawn in the 3-D panel [m].
PatchSide = Annotated[float, Field(gt=0, lt=10)]


class ConsoleParams(ArmParams):
    """:class:`~umbra.modules.operator.console.OperatorConsole`'s parameters (``robot`` /
    ``dh_file``: the arm whose joint limits are shown)."""

    serve: bool = param(True, "serve the page (false: no web server, for batch trials)")
    host: str = param("127.0.0.1", "address to listen on (the access token is always needed)")
    port: int = param(0, "TCP port (0: a free one, printed at start)", ge=0, le=MAX_TCP_PORT)
    token_file: str = param("", "file whose first line is the access token (else a random one)")
    stale_page_s: float = param(
        0.5, "actions on an image older than this are refused", unit="s", gt=0
    )
    max_contour_age: float = param(
        0.5, "resume/start need a contour at most this old", unit="s", gt=0
    )
    deadman_s: float = param(
        0.15, "jog stops when no keep-alive came this long", unit="s", gt=0, le=1.0
    )
    jog_linear: float = param(0.02, "full-speed jog, linear", unit="m/s", gt=0, le=0.25)
    jog_angular: float = param(0.2, "full-speed jog, roll", unit="rad/s", gt=0, le=1.0)
    camera_frame: str = param("camera", "frame of the jog output (REG_VEL's frame)")
    tool_frame: str = param("tool", "frame of tool-frame jogs")
    jpeg_quality: int = param(80, "JPEG quality of the video", ge=10, le=100)
    state_rate_hz: float = param(
        10.0,
        "page updates per second (at least two in the time a page waits on a silent socket)",
        unit="Hz",
        ge=2.0 / PAGE_SILENT_S,
        le=60,
    )
    zoom_names: list[str] = param(
        [],
        "cameras with a zoom slider, in the order of outputs zoom_1, zoom_2 (max 2, distinct)",
        max_length=2,
    )
    view_fov_deg: float = param(
        77.3,
        "3-D panel: the camera's horizontal field of view",
        unit="deg",
        gt=1,
        lt=179,
    )
    patch_size_m: list[PatchSide] = param(
        [0.06, 0.04],
        "3-D panel: the patch's sides drawn at patch_pose",
        unit="m",
        min_length=2,
        max_length=2,
    )
    rectangle_margin: float = param(0.12, "outer rectangle growth, as the snake's", ge=0)
    ellipse_scale: float = param(0.85, "inner ellipse scale, as the snake's", gt=0, le=1)

    @field_validator("zoom_names")
    @classmethod
    def _distinct(cls, names: list[str]) -> list[str]:
        if len(set(names)) != len(names):
            raise ValueError(f"expected distinct camera names, found {names}")
        return names
