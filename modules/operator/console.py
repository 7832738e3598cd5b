"""OperatorConsole: the operator's live station in the browser, with the operator in the loop."""

from __future__ import annotations

import collections
import math
import socket
import time
from typing import TYPE_CHECKING, Any

import numpy as np

from umbra.connectors import Input, Module, Output, from_param
from umbra.connectors.access.secret import resolve_token
from umbra.connectors.commands import GrabCommand, Seed, StopRun
from umbra.connectors.messages import (
    Contour,
    Image,
    JointState,
    Pose,
    Poses,
    Scalar,
    Twist,
)
from umbra.connectors.path_messages import ToolPath, VcrState
from umbra.connectors.sketch_messages import SketchPrimitive, StereoSnapshot
from umbra.connectors.states import GuardState, Presence, ServoStage, ServoState, Verdict
from umbra.modules.operator import view_state
from umbra.modules.operator.actions import FrameHistory, ShownFrame
from umbra.modules.operator.console_events import ConsoleEvents
from umbra.modules.operator.console_params import ConsoleParams
from umbra.modules.operator.console_view import ConsoleView
from umbra.modules.operator.control import ControlArbiter
from umbra.modules.operator.cpu import process_cpu_s
from umbra.modules.operator.jog import KEEPALIVE_S, DeadMan, JogFrame, JogLimits, JogStop, jog_twist
from umbra.modules.operator.jog_labels import jog_labels
from umbra.modules.operator.mailbox import Lanes
from umbra.modules.operator.message_board import MessageBoard
from umbra.modules.operator.sketch_scene import SketchItems
from umbra.modules.operator.web_figures import cpu_figures, web_figures
from umbra.modules.vision.sanity import SanityLimits

if TYPE_CHECKING:  # the web side is imported only when the console serves (not in batch trials)
    from umbra.modules.operator.console_app import ConsoleApp, Event
    from umbra.modules.operator.web_server import WebServer

#: the plots' longest window [s] and the spacing of their points [s]
PLOT_WINDOW_S = 120.0
ERROR_PERIOD_S = 0.1
#: how long [s] the stopping console waits, at most, for its open pages to get the run's end (a
#: loaded web thread has been seen to need more than 1 s); a page that misses it gets it when it
#: reconnects, for as long as the server lingers (``linger.END_LINGER_S``)
END_FLUSH_S = 3.0


class OperatorConsole(Module[ConsoleParams]):
    """The operator's console: a web page (127.0.0.1 by default) with the live camera image, the
    snake drawn over it in the browser, the grab's stage and errors, link and arm health, and
    the operator's actions as outputs: ``seed`` (click: [u, v]; dragged box: [u0, v0, u1, v1]),
    ``operator`` (start / pause / resume / abort for vsServo), ``stop_run`` (*Stop*: the run ends,
    judged by the world) and ``jog`` (dead-man teleoperation
    twist in ``camera_frame``, for REG_VEL's ``jog`` input: at each keep-alive from the page and
    at the keep-alive period while the dead-man holds it, zero once it expires or is released).

    Many pages may watch; one holds control, and only its commands pass (the others are refused
    and counted). Every page, route and socket needs the per-run access token (``token_file``, or
    a random one printed in the address at start), loopback too (:mod:`umbra.modules.webdoor`). A
    seed from the simulated operator (``sim_seed``) is passed on only while no person has taken
    control. The address is logged at start. ``serve: false`` runs
    without a web server (batch trials): only the simulated operator's seed is passed on.
    """

    TYPE = "OperatorConsole"

    Params = ConsoleParams

    image = Input(Image, trigger=True, doc="camera frames (BGR)")
    contour = Input(Contour, required=False, doc="snake contour, drawn over the image")
    servo = Input(ServoState, required=False, doc="vsServo's state: stage, errors, assistance")
    guard = Input(GuardState, required=False, doc="REG_VEL's state: passing, or zero and why")
    joints = Input(JointState, required=False, feedback=True, doc="measured joint state")
    world = Input(Verdict, required=False, feedback=True, doc="simulated world: grasp verdict")
    link_poses = Input(
        Poses, required=False, feedback=True, doc="3-D panel: T_base_link of the arm's links"
    )
    camera_pose = Input(
        Pose, required=False, feedback=True, doc="3-D panel: the wrist camera (T_table_camera)"
    )
    patch_pose = Input(
        Pose, required=False, feedback=True, doc="3-D panel: the tool's patch (T_table_patch)"
    )
    snapshot = Input(StereoSnapshot, required=False, doc="3-D panel: Active Sketch's snapshots")
    primitive = Input(SketchPrimitive, required=False, doc="3-D panel: placed primitives")
    path = Input(ToolPath, required=False, doc="3-D panel: the path loaded into the player")
    vcr_state = Input(
        VcrState, required=False, feedback=True, doc="3-D panel: the player's place on the path"
    )
    sim_seed = Input(Seed, required=False, doc="the simulated operator's click")
    zoom_auto = Input(
        Scalar, required=False, doc="zoom request passed to every zoom output until a person zooms"
    )
    seed = Output(Seed, events=True, doc="seed for vsSnake: a clicked point or a dragged box, px")
    operator = Output(
        GrabCommand, events=True, doc="grab command for vsServo: start / pause / resume / abort"
    )
    jog = Output(
        Twist,
        frame=from_param("camera_frame"),
        origin_from=("image",),  # a jog is as old as the picture the operator acts on
        doc="dead-man jog twist for REG_VEL: at the keep-alive period while the jog is held, "
        "zero on release",
    )
    stop_run = Output(
        StopRun,
        events=True,
        doc="the operator's *Stop*, for the judge of the run (the world), which ends it as a "
        "normal stop with the verdict 'stopped by the operator'",
    )
    presence = Output(
        Presence, doc="whether a person holds control, has acted, and how many pages are open"
    )
    zoom_1 = Output(
        Scalar, events=True, doc="zoom requests 0 (wide) .. 1 (tele) for camera zoom_names[0]"
    )
    zoom_2 = Output(
        Scalar, events=True, doc="zoom requests 0 (wide) .. 1 (tele) for camera zoom_names[1]"
    )

    # -- lifecycle ----------------------------------------------------------------------------
    def start(self) -> None:
        p = self.params
        arm = p.table
        self._q_limits = (arm.q_min, arm.q_max, arm.qd_max)
        self._limits = SanityLimits(
            rectangle_margin=p.rectangle_margin, ellipse_scale=p.ellipse_scale
        )
        try:  # T_tool_camera: a tool-frame jog is sent in the camera frame
            self._T_tool_camera: np.ndarray | None = self.context.frames.lookup(
                p.tool_frame, p.camera_frame
            )
        except KeyError:
            self._T_tool_camera = None  # tool-frame jogs are refused (no static frame)
        #: the jog buttons' names in both frames (the camera's mount is static)
        self._jog_labels = {f: jog_labels(f, self._T_tool_camera) for f in JogFrame}
        self._jog_limits = JogLimits(p.jog_linear, p.jog_angular)
        self.arbiter = ControlArbiter()
        self.deadman = DeadMan(p.deadman_s)
        self.history = FrameHistory()
        self.lanes: Lanes[Event] = Lanes()
        self.board = MessageBoard()
        self.sketch_items = SketchItems()  #: Active Sketch's items for the 3-D panel
        self._phase_ended = False  #: set by stop(): the page shows the run's end
        self._jogging = False
        self._keepalive = False  #: a held jog's keep-alive arrived since the last step
        self._jog_sent_at = -math.inf  #: wall time [s] the held jog's twist was last sent
        self._jog_since = math.inf  #: when [s] the held jog began
        self._last_state = -math.inf
        self._state_period = 1.0 / p.state_rate_hz
        self._last_presence: tuple[str, int, int] | None = None
        self._last_servo_stage = ""
        self._assist: dict[str, Any] | None = None
        #: [t s, x m, y m, z m, roll rad] at most every ERROR_PERIOD_S, the last PLOT_WINDOW_S
        self._errors: collections.deque[list[float]] = collections.deque(
            maxlen=int(PLOT_WINDOW_S / ERROR_PERIOD_S)
        )
        self._t0: float | None = None
        self._last_now = 0.0  #: the latest step's time [s]
        self.counts: collections.Counter[str] = collections.Counter()
        #: per seed from a page: (wall time the click reached the web thread, wall time sent) [s]
        self.seed_sent_wall: list[tuple[float, float]] = []
        self._server: WebServer | None = None
        self._refused_requests = 0  #: requests the token gate refused (kept after stop)
        self._app: ConsoleApp | None = None
        self.url = ""
        self._cpu0 = process_cpu_s()
        self._zoom = dict.fromkeys(p.zoom_names, 0.0)  #: commanded zoom per camera
        self.events = ConsoleEvents(self)  #: what the pages send
        self.view = ConsoleView(self)  #: what the pages show
        if p.serve:
            from umbra.modules.operator.console_app import ConsoleApp
            from umbra.modules.operator.web_server import acquire_server

            token = resolve_token(p.token_file, self.name)
            self._server = acquire_server(self.context, p.host, p.port, token)
            self.arbiter = self._server.control  # one holder for every page of the server
            self._app = ConsoleApp(self._server, self.lanes, p.jpeg_quality)
            self.url = self._server.url
            self.log.info("operator console: %s", self.url)
            if p.host in ("0.0.0.0", "::"):  # every interface: name this machine for others
                self.log.info(
                    "operator console: from another computer open %s (plain HTTP: the token "
                    "travels in clear; prefer an SSH tunnel to a loopback console)",
                    self.url.replace(
                        self.url.split("/")[2].rsplit(":", 1)[0], socket.gethostname()
                    ),
                )

    def stop(self) -> None:
        self._cpu_end = self._cpu_figures()
        self._phase_ended = True
        if self._app is not None:  # the run's end, for the pages open now and those to come
            self._app.flush_final(self.view.state(self._last_now), END_FLUSH_S)
        if self._server is not None:  # kept for the summary (the server goes below)
            self._refused_requests = self._server.refused_requests
        if self._app is not None:
            self._app.close()
        if self._server is not None:
            from umbra.modules.operator.web_server import release_server
            from umbra.modules.webdoor.linger import END_LINGER_S

            # a page that reconnects after the end still gets it (and its verdict)
            release_server(self._server, END_LINGER_S)
            self._server = None

    # -- step ---------------------------------------------------------------------------------
    def step(self, now: float) -> None:
        if self._t0 is None:
            self._t0 = now
        self._last_now = now
        wall = time.monotonic()
        self._video(now)
        self._sketch_items(now)
        for event in self.lanes.drain():
            self.events.handle(event, now)
        self.lanes.set_holders(frozenset(s for s in self.arbiter.sessions if self.arbiter.holds(s)))
        self._sim_seed(now)
        self.events.zoom_auto(now)
        self._jog_step(now, wall)
        self._track_servo(now)
        self._presence()
        app = self._app
        if app is None or not app.stats.viewers:
            return  # nobody watches: no page state
        self.view.track_links(now)
        if now - self._last_state >= self._state_period:
            self._last_state = now
            app.state.put(self.view.state(now))

    def _video(self, now: float) -> None:
        if not self.image.fresh:
            return
        image = self.image.get(now)
        if image is None:
            return
        pixels = np.asarray(image.pixels)
        # dated by its capture (origin; its arrival while the clocks cannot date it), as the
        # page dates the picture it shows: a refusal's age is the page's shown age, later
        capture = image.origin if math.isfinite(image.origin) else self.image.received_at
        self.history.add(ShownFrame(image.seq, capture, pixels.shape[1], pixels.shape[0]))
        if self._app is not None:
            self._app.frames.put(self._app.raw_frame(pixels, image.seq, time.time(), now - capture))

    def _sketch_items(self, now: float) -> None:
        items = self.sketch_items
        if self.snapshot.fresh and (snap := self.snapshot.get(now)) is not None:
            items.add_snapshot(snap)
        if self.primitive.fresh and (prim := self.primitive.get(now)) is not None:
            items.add_primitive(prim)
        if self.path.fresh and (path := self.path.get(now)) is not None:
            items.set_path(path)

    # -- periodic -----------------------------------------------------------------------------
    def _jog_step(self, now: float, wall: float) -> None:
        """The held jog's twist at each keep-alive, and at the keep-alive period of this clock
        while the dead-man holds it (a late keep-alive does not zero the arm between two; the
        register's watchdog zeroes the jog when this console goes silent); a zero twist once,
        when the jog is released, its page goes, the dead-man expires or the guard (REG_VEL)
        held the jog at zero since it began: then the page is told why, and the hold stays
        stopped until released (one motion, not bursts)."""
        keepalive, self._keepalive = self._keepalive, False
        before, expired = self.deadman.held, self.deadman.expired
        held = self.deadman.current(wall)
        if before is not None and self.deadman.expired > expired:  # its page went silent
            self.events.notice(self.deadman.stopped[before.session].detail, before.session, "error")
        if held is not None and not self.arbiter.holds(held.session):
            self.deadman.release()
            held = None
        if held is not None and not self._jogging:
            self._jog_since = now  #: the guard's word counts from the hold's start [s]
        guard = self.guard.value
        if (
            held is not None
            and self._jogging
            and guard is not None
            and guard.jog
            and not guard.passing
            and self.guard.received_at > self._jog_since
        ):
            why = f"{JogStop.GUARD.words}: {guard.code.words}"
            self.deadman.stop(held.session, JogStop.GUARD, why)
            self.events.notice(why, held.session, "error", detail=guard.reason)
            held = None
        if held is not None:
            if keepalive or wall - self._jog_sent_at >= KEEPALIVE_S:
                self._jog_sent_at = wall
                T = self._T_tool_camera if self._T_tool_camera is not None else np.eye(4)
                twist = jog_twist(held.axes, held.speed, held.jog_frame, self._jog_limits, T)
                self.jog.send(Twist(vector=twist, frame=self.params.camera_frame))
                self._jogging = True
        elif self._jogging:
            self.jog.send(Twist(vector=np.zeros(6), frame=self.params.camera_frame))
            self._jogging = False

    def _sim_seed(self, now: float) -> None:
        click = self.sim_seed.value
        if not self.sim_seed.fresh or click is None:
            return
        if self.arbiter.person_acted:
            self.counts["sim_seeds_ignored"] += 1
            return
        self.seed.send(Seed(shape=click.shape, uv=np.asarray(click.uv, dtype=float)))
        self.counts["sim_seeds"] += 1

    def _presence(self) -> None:
        key = (
            "person" if self.arbiter.holder else "nobody",
            int(self.arbiter.person_acted),
            len(self.arbiter.sessions),
        )
        if key != self._last_presence:
            self._last_presence = key
            self.presence.send(
                Presence(
                    person=bool(self.arbiter.holder),
                    acted=bool(key[1]),
                    viewers=key[2],
                    holder=self.arbiter.holder_name(),
                )
            )

    def _track_servo(self, now: float) -> None:
        status = self.servo.get(now)
        if status is None or not self.servo.fresh:
            return
        errs = [status.values.get(n, math.nan) for n in view_state.ERRORS]
        t = self._run_time()
        if any(math.isfinite(e) for e in errs) and (
            not self._errors or t - self._errors[-1][0] >= ERROR_PERIOD_S - 1e-6
        ):
            self._errors.append([t, *errs])
        if status.stage == ServoStage.ASSIST and self._last_servo_stage != ServoStage.ASSIST:
            reason = status.reason or status.message
            plain = status.words()
            self._assist = {
                "id": self.counts["assists"] + 1,
                "reason": reason,
                "plain": plain,
                "overlay": view_state.overlay(self.contour.value, self._limits),
            }
            self.counts["assists"] += 1
            if self._app is not None and self.image.value is not None:
                self._app.assist_frame.put(np.array(self.image.value.pixels))  # kept: a copy
            lead = "the grab stopped and asks for you"
            self.board.post_reason(lead, plain, reason, self._run_time())
            self.log.warning("console: assistance requested: %s", reason)
        elif status.stage != ServoStage.ASSIST:
            self._assist = None
        self._last_servo_stage = status.stage

    def _run_time(self) -> float:
        """Seconds since the console's first step (the page's time axis)."""
        return round(self._last_now - (self._t0 if self._t0 is not None else self._last_now), 3)

    # -- summary ------------------------------------------------------------------------------
    def _cpu_figures(self) -> dict[str, float]:
        return {} if self._app is None else cpu_figures(self._app.stats, self._cpu0)

    def summary(self) -> dict[str, object]:
        out: dict[str, object] = {
            "url": self.url.split("?")[0],  # not the token: summaries are files
            "seeds": self.counts["seeds"],
            "sim_seeds": self.counts["sim_seeds"],
            "sim_seeds_ignored": self.counts["sim_seeds_ignored"],
            "refused": self.counts["refused"],
            "refused_others": self.counts["refused_others"],
            "bad_messages": 0
            if self._app is None
            else self._app.stats.malformed + self._app.stats.replayed,
            "control_refusals": self.arbiter.refused,
            "person_acted": self.arbiter.person_acted,
            "jogs": self.counts["jogs"],
            "deadman_expired": self.deadman.expired,
            "assists": self.counts["assists"],
        }
        if self._app is not None:
            out.update(web_figures(self._app.stats, self.seed_sent_wall))
            out["refused_requests"] = (
                self._server.refused_requests if self._server else self._refused_requests
            )
            out.update(getattr(self, "_cpu_end", {}))
        return out
