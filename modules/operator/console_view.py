"""What the console's page shows: the state snapshot built from the console's inputs (a part
that :class:`~umbra.modules.operator.console.OperatorConsole` owns; its ``step`` hands the
snapshot to the web side)."""

from __future__ import annotations

import itertools
import math
from typing import TYPE_CHECKING, Any

import numpy as np

from umbra.connectors.states import NO_AGE_S, GuardReason
from umbra.modules.operator import view_state
from umbra.modules.operator.jog import KEEPALIVE_S
from umbra.modules.operator.scene_view import scene_view
from umbra.modules.operator.state_line import commands_available, phase_of, state_line

if TYPE_CHECKING:
    from umbra.modules.operator.console import OperatorConsole

#: The clocks of the graph's processes agree within this [s] for the page to say "in sync".
CLOCK_SYNC_BOUND_S = 0.005
#: The page gets the whole error history this often [s]; in between only the rows since the
#: previous page state (a page that skipped a state is whole again within this time).
ERRORS_FULL_PERIOD_S = 2.0
#: A zero shorter than this [s] is not shown as the arm held (it is counted, not flashed).
BANNER_HOLD_S = 0.15
#: The page shows its picture's age amber from this fraction of ``stale_page_s`` (the bound
#: past which the console refuses an action made on it: red), so the operator sees a refusal
#: coming.
FRAME_AGE_WARN_FRACTION = 0.5


class ConsoleView:
    """The page state of an :class:`~umbra.modules.operator.console.OperatorConsole`: reads the
    console's inputs, control table, notices and counters; keeps the links' ages, the held
    banner's start, the error rows already sent and the static frames it looked up."""

    def __init__(self, console: OperatorConsole) -> None:
        self._c = console
        self._link_age: dict[str, float] = {}  #: oldest age per input since the last page update
        #: (stamp, origin) [s] of each input's sample last seen
        self._link_seen: dict[str, tuple[float, float]] = {}
        self._zero_since: float | None = None  #: when the guard's present zero began [s]
        self._errors_full_at = -math.inf  #: when the page last got the whole error history [s]
        self._errors_sent_t = -math.inf  #: run time of the last error row sent [s]
        #: static transforms the 3-D panel looked up, by (parent, child) (None: not connected)
        self._static: dict[tuple[str, str], np.ndarray | None] = {}

    def _links(self) -> tuple[tuple[str, Any], ...]:
        c = self._c
        return (
            ("image", c.image),
            ("contour", c.contour),
            ("servo", c.servo),
            ("joints", c.joints),
        )

    def track_links(self, now: float) -> None:
        """The oldest each input's latest sample got since the last page update [s], counted
        from its producer's stamp (on this process's clock): now, or when the next one replaced
        it. About its period while it flows, growing when it stops or falls behind (an age at
        arrival would read 0 for a sample computed from the past)."""
        ages, seen = self._link_age, self._link_seen
        for name, reg in self._links():
            sample = reg.value
            if sample is None:
                continue
            age = now - sample.stamp
            before = seen.get(name)
            if before is not None and sample.stamp > before[0]:  # the one before, when replaced
                age = max(age, reg.received_at - before[0])
            seen[name] = (sample.stamp, sample.origin)
            if age > ages.get(name, -math.inf):
                ages[name] = age

    def _data_ages(self, now: float) -> dict[str, Any]:
        """The end-to-end age [ms] of the data behind the command REG_VEL passes (image capture
        to the register), whether it is held for old data, and the clocks' agreement."""
        guard = self._c.guard.value
        errors = [reg.clock_error for _n, reg in self._links() if reg.value is not None]
        worst = max(errors, default=0.0)
        problems = [reg.clock_problem for _n, reg in self._links() if reg.clock_problem]
        return {
            "command_origin_ms": None
            if guard is None or guard.origin_age_s >= 0.1 * NO_AGE_S
            else round(guard.origin_age_s * 1e3, 1),
            "command_stale": guard is not None and guard.stale,
            "clock_error_ms": None if not math.isfinite(worst) else round(worst * 1e3, 3),
            "clocks_synced": math.isfinite(worst) and worst <= CLOCK_SYNC_BOUND_S,
            "clock_problem": problems[0] if problems else "",
        }

    def held_banner(self, now: float, servo: Any, guard: Any) -> str:
        """The red "at zero" banner, only while the arm is actually held: at once for a request,
        old data or a lost process; for the link watchdog (a command that came late) once it
        lasted ``BANNER_HOLD_S`` (a late command or two is counted in the summary, not flashed)."""
        text = view_state.zero_banner(servo, guard)
        if not text:
            self._zero_since = None
            return ""
        if self._zero_since is None:
            self._zero_since = now
        blip = guard is not None and guard.code == GuardReason.WATCHDOG and not guard.jog
        return text if not blip or now - self._zero_since >= BANNER_HOLD_S else ""

    def frame_age_bounds(self) -> dict[str, float]:
        """The bounds [ms] on the age of the picture the page shows, from its capture:
        ``limit_ms`` is the console's own ``stale_page_s`` (an action on an older picture is
        refused: red), ``warn_ms`` where the page turns amber."""
        limit = self._c.params.stale_page_s
        return {
            "limit_ms": round(limit * 1e3, 3),
            "warn_ms": round(limit * FRAME_AGE_WARN_FRACTION * 1e3, 3),
        }

    def error_rows(self, now: float) -> dict[str, Any]:
        """The servo errors for the plot: ``errors`` rows (page units) and ``errors_full``
        (True: the whole history, which replaces the page's; False: the rows since the previous
        state, which extend it)."""
        full = now - self._errors_full_at >= ERRORS_FULL_PERIOD_S
        if full:
            self._errors_full_at = now
            rows = list(self._c._errors)
        else:  # only the rows since the previous state: walk back from the newest
            sent = self._errors_sent_t
            rows = list(itertools.takewhile(lambda r: r[0] > sent, reversed(self._c._errors)))
            rows.reverse()
        if rows:
            self._errors_sent_t = rows[-1][0]
        return {"errors": view_state.error_rows(rows), "errors_full": full}

    def _panels(self) -> dict[str, bool]:
        """Which panels this graph feeds (a graph without some module lacks its panel)."""
        links = self._c._server.links if self._c._server is not None else {}
        return {
            "video": True,
            "controls": self._c.operator.connected or self._c.seed.connected,
            "plot": self._c.servo.value is not None,
            "jog": self._c.jog.connected,
            "health": True,
            "messages": True,
            "zoom": bool(self._c._zoom),
            "sketch": "/sketch" in links,
            "view3d": self._c.link_poses.value is not None,
        }

    def scene(self, now: float) -> dict[str, Any] | None:
        """The 3-D panel's scene (None: no arm in this graph)."""
        latest = self._c.history.latest
        aspect = latest.width / latest.height if latest is not None else 16 / 9
        p = self._c.params
        links, camera, patch = (
            r.get(now) for r in (self._c.link_poses, self._c.camera_pose, self._c.patch_pose)
        )
        base = links.frame if links is not None else ""
        scene = scene_view(
            links,
            camera,
            patch,
            None if camera is None else self._static_pose(base, camera.parent),
            None if patch is None else self._static_pose(base, patch.parent),
            p.view_fov_deg,
            aspect,
            (p.patch_size_m[0], p.patch_size_m[1]),
        )
        if scene is not None and self._c.sketch_items:
            scene["sketch"] = self._c.sketch_items.view(
                lambda frame: self._static_pose(base, frame), self._c.vcr_state.get(now)
            )
        return scene

    def _static_pose(self, parent: str, child: str) -> Any:
        """T_parent_child from the graph's static frames, looked up once (None: not tied)."""
        key = (parent, child)
        if key not in self._static:
            try:
                self._static[key] = self._c.context.frames.lookup(parent, child)
            except KeyError:
                self._static[key] = None
        return self._static[key]

    def state(self, now: float) -> dict[str, Any]:
        servo = self._c.servo.get(now)
        guard = self._c.guard.get(now)
        world = self._c.world.get(now)
        held = self._c.deadman.held
        stopped = self._c.deadman.stopped.get(self._c.arbiter.holder or "")
        phase = phase_of(self._c.history.latest is not None, self._c._phase_ended)
        contour = self._c.contour.get(now)
        line = state_line(
            phase, servo, guard, world, self._c.arbiter.holder_name(), held is not None, contour
        )
        return {
            "t": self._c._run_time(),
            "phase": phase,
            "line": line.for_page(),
            "commands": commands_available(phase, line.stage, self._c.stop_run.connected),
            "panels": self._panels(),
            "overlay": view_state.overlay(contour, self._c._limits),
            "frame_age": self.frame_age_bounds(),
            "scene": self.scene(now),
            "servo": view_state.servo_view(servo),
            "banner": self.held_banner(now, servo, guard),
            "data_age": self._data_ages(now),
            "guard": None if guard is None else {"stage": guard.stage, "reason": guard.reason},
            "world": None
            if world is None
            else {"stage": world.stage, "message": world.message, "values": world.values},
            **self.error_rows(now),
            "links": [
                view_state.link_view(
                    name,
                    self._link_age.pop(name, math.inf),
                    reg.link_alive,
                    math.inf if reg.value is None else now - reg.value.origin,
                )
                for name, reg in self._links()
            ],
            "smart_alive": None  # nothing from the servo side yet (or none in this graph)
            if self._c.joints.value is None and self._c.guard.value is None
            else self._c.joints.link_alive and self._c.guard.link_alive,
            "joints": view_state.joints_view(self._c.joints.get(now), *self._c._q_limits),
            "control": self._c.arbiter.holder_name(),
            "control_session": self._c.arbiter.holder or "",
            "viewers": [name for name in self._c.arbiter.sessions.values()],
            "refused": self._c.counts["refused_others"],
            "jog": None
            if held is None
            else {"axes": held.axes, "frame": held.jog_frame, "speed": held.speed},
            "jog_labels": self._c._jog_labels,
            "jog_keepalive_ms": KEEPALIVE_S * 1e3,
            #: why the holder's held jog was stopped (it stays so until released), None: not
            "jog_stopped": None if stopped is None else stopped.view(),
            "assist": self._c._assist,
            "zoom": [{"name": k, "value": round(v, 3)} for k, v in self._c._zoom.items()],
            "notices": self._c.board.for_page(),
            "links_extra": dict(self._c._server.links) if self._c._server is not None else {},
        }
