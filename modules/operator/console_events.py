"""The console's handling of what its pages send: control, seeds, grab commands, zoom and the
dead-man jog (a part that :class:`~umbra.modules.operator.console.OperatorConsole` owns; every
action ends as one of the console's typed outputs or as a refusal with the reason, told to the
page that sent it)."""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING, Any

import numpy as np

from umbra.connectors.commands import GrabAction, GrabCommand, Seed, StopRun
from umbra.connectors.messages import Scalar
from umbra.modules.operator.actions import Refused, box_seed, check_snake_healthy, point_seed
from umbra.modules.operator.jog import JogFrame, JogStop
from umbra.modules.operator.protocol import STOP_ACTION
from umbra.modules.servo.stages import ACTIVE_STAGES

if TYPE_CHECKING:
    from umbra.modules.operator.console import OperatorConsole
    from umbra.modules.operator.console_app import Event


class ConsoleEvents:
    """Page events for the console: reads and writes the console's ports and tables; keeps
    when each page's refusals were last logged and whether a person has zoomed."""

    def __init__(self, console: OperatorConsole) -> None:
        self._c = console
        self._logged_refusal: dict[str, tuple[float, int]] = {}  #: session -> (wall, count)
        self._person_zoomed = False  #: a person zoomed: automatic zoom requests stop

    def notice(
        self,
        text: str,
        session: str = "*",
        level: str = "info",
        log: bool = True,
        detail: str = "",
    ) -> None:
        """Tell the page ``session`` (``*``: every page) ``text`` (a repeat is counted on its
        line, not added), with the exact ``detail`` behind it; log it unless ``log`` is False."""
        self._c.board.post(text, self._c._run_time(), session, level, detail)
        if not log:
            return
        who = self._c.arbiter.sessions.get(session, "console") if session != "*" else "console"
        (self._c.log.warning if level == "error" else self._c.log.info)(
            "%s: %s", who, detail or text
        )

    def _refuse(self, session: str, text: str) -> None:
        """Tell the page ``session`` why; the log says it at most once a second per page (a page
        sending refused commands in a flood is not a flood of log lines). Refusals of pages
        without control are counted apart (the holder's own, e.g. a stale click, are not
        another operator knocking)."""
        self._c.counts["refused"] += 1
        if not self._c.arbiter.holds(session):
            self._c.counts["refused_others"] += 1
        wall = time.monotonic()
        last, count = self._logged_refusal.get(session, (-math.inf, 0))
        if wall - last >= 1.0:
            more = self._c.counts["refused"] - count - 1 if count else 0
            text_log = f"{text} (and {more} more refusals since)" if more > 0 else text
            self._logged_refusal[session] = (wall, self._c.counts["refused"])
            who = self._c.arbiter.sessions.get(session, "console")
            self._c.log.warning("%s: %s", who, text_log)
        self.notice(text, session, "error", log=False)

    # -- events from the pages ----------------------------------------------------------------
    def handle(self, event: Event, now: float) -> None:
        s = event.session
        if event.kind == "join":
            self._c.arbiter.join(s, event.payload, event.browser)
            self.notice(f"{event.payload} is watching")
        elif event.kind == "leave":
            self._c.deadman.release(s)
            self._logged_refusal.pop(s, None)
            name = self._c.arbiter.sessions.get(s, s)
            if self._c.arbiter.leave(s):
                self.notice(f"{name} disconnected; control is free")
        elif event.kind == "msg":
            self._message(s, event.payload.type, event.payload.fields, now, event.wall)

    def _message(self, s: str, kind: str, f: dict[str, Any], now: float, wall: float) -> None:
        if kind == "hello":
            return
        if kind in ("take", "release"):
            decision = self._c.arbiter.take(s) if kind == "take" else self._c.arbiter.release(s)
            if kind == "release" and decision.ok:
                self._c.deadman.release(s)
            if decision.ok:
                self.notice(decision.message)
            else:
                self._refuse(s, decision.message)
            return
        what = f.get("action", kind)
        decision = self._c.arbiter.may_command(s, what)
        if not decision.ok:
            self._c.deadman.release(s)
            self._refuse(s, decision.message)
            return
        try:
            if kind == "jog":
                self._jog_message(s, f, now, wall)
            elif kind == "click":
                frame = self._c.history.frame_for(f["frame"], now, self._c.params.stale_page_s)
                self._send_seed(point_seed(frame, f["u"], f["v"]), wall, "click")
            elif kind == "box":
                frame = self._c.history.frame_for(f["frame"], now, self._c.params.stale_page_s)
                box = box_seed(frame, f["u0"], f["v0"], f["u1"], f["v1"])
                self._send_seed(box, wall, "box")
            elif kind == "zoom":
                self._zoom_message(f["camera"], f["value"])
            elif kind == "action":
                self._action(s, f["action"], now)
            else:
                raise Refused(f"{kind} is not available on this console")
        except Refused as exc:
            self._refuse(s, str(exc))

    def _send_seed(self, seed: Seed, wall: float, what: str) -> None:
        self._c.seed.send(seed)
        self._c.seed_sent_wall.append((wall, time.monotonic()))
        self._c.counts["seeds"] += 1
        where = ", ".join(f"{v:.1f}" for v in seed.uv)
        self.notice(f"{what} seed sent to the snake at [{where}] px")

    def _action(self, s: str, action: str, now: float) -> None:
        if action == STOP_ACTION:
            self._stop_run()
            return
        grab = GrabAction(action)  # the protocol passes only these and stop
        if grab in (GrabAction.RESUME, GrabAction.START):
            check_snake_healthy(
                self._c.contour.get(now),
                self._c.contour.age(now),
                self._c.params.max_contour_age,
                action,
            )
        self._c.operator.send(GrabCommand(action=grab))
        self._c.counts[action] += 1
        self.notice(f"{action} sent to vsServo")

    def _stop_run(self) -> None:
        """*Stop*: ask the run's judge (the world) to end the run; it says the verdict."""
        if not self._c.stop_run.connected:
            raise Refused(
                "stop refused: expected a judge of the run (the world's `operator` input) "
                "connected to the console's `stop_run`, found none (Ctrl-C ends this run)"
            )
        self._c.stop_run.send(StopRun(by=self._c.arbiter.holder_name()))
        self._c.counts[STOP_ACTION] += 1
        self.notice("stop sent: the run ends (its summary and recordings are written)")

    def _zoom_message(self, camera: str, value: float) -> None:
        if camera not in self._c._zoom:
            raise Refused(
                f"zoom refused: expected a camera of {list(self._c._zoom)}, found {camera!r}"
            )
        if not 0.0 <= value <= 1.0:
            raise Refused(f"zoom refused: expected 0 (wide) .. 1 (tele), found {value}")
        self._person_zoomed = True
        self._send_zoom(camera, value)

    def _send_zoom(self, camera: str, value: float) -> None:
        self._c._zoom[camera] = value
        port = (self._c.zoom_1, self._c.zoom_2)[self._c.params.zoom_names.index(camera)]
        port.send(Scalar(value=float(value)))

    def zoom_auto(self, now: float) -> None:
        """Pass the console's ``zoom_auto`` request to every camera until a person zooms."""
        port = self._c.zoom_auto
        if not port.fresh or port.value is None or self._person_zoomed:
            return
        value = float(np.clip(port.value.value, 0.0, 1.0))
        for camera in self._c._zoom:
            self._send_zoom(camera, value)

    def _jog_message(self, s: str, f: dict[str, Any], now: float, wall: float) -> None:
        if f["held"] and s in self._c.deadman.stopped:
            return  # a hold stopped (the page was told why) stays stopped until released
        if f["held"]:  # nobody jogs blind: the page must show live video (a release always goes)
            try:
                self._c.history.frame_for(f["frame"], now, self._c.params.stale_page_s)
            except Refused as exc:
                why = f"jog refused: {exc}"
                self._c.deadman.stop(s, JogStop.STALE_PICTURE, why)
                raise Refused(why) from None
        if f["held"] and f["jog_frame"] == JogFrame.TOOL and self._c._T_tool_camera is None:
            raise Refused(
                f"tool-frame jog refused: expected a static frame {self._c.params.tool_frame}->"
                f"{self._c.params.camera_frame} in the graph, found none (jog in the camera frame)"
            )
        was = self._c.deadman.held
        self._c.deadman.update(s, f["held"], f["axes"], f["speed"], f["jog_frame"], wall)
        self._c._keepalive = self._c.deadman.held is not None
        if self._c.deadman.held is not None and was is None:
            self._c.counts["jogs"] += 1
            servo = self._c.servo.value
            if servo is not None and servo.stage in ACTIVE_STAGES:
                self._c.operator.send(GrabCommand(action=GrabAction.PAUSE))
                self.notice("jog: the grab is paused (resume it when done)")
