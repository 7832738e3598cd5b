"""What the console's page shows: the state snapshot built from the console's inputs (read by
:class:`~modules.operator.console.OperatorConsole`'s ``step``, handed to the web side)."""

from __future__ import annotations

import math
from typing import Any

from modules.operator import view_state


class ConsoleView:
    """The page state of an :class:`~modules.operator.console.OperatorConsole` (a mixin: it
    reads the console's inputs, control table, notices and counters)."""

    def _links(self) -> tuple[tuple[str, Any], ...]:
        return (
            ("image", self.image),
            ("contour", self.contour),
            ("servo", self.servo),
            ("joints", self.joints),
        )

    def _track_links(self, now: float) -> None:
        """The oldest each input's latest sample got since the last page update [s]: now, or
        when the next one replaced it. About its period while it flows, growing when it stops
        (the age at a step alone is often 0: a sample comes with the tick that runs the console,
        and a busy process runs it only then)."""
        ages, seen = self._link_age, self._link_seen
        for name, reg in self._links():
            age = reg.age(now)
            before = seen.get(name)
            if before is not None and math.isfinite(before) and reg.received_at > before:
                age = max(age, reg.received_at - before)  # the one before, when replaced
            seen[name] = reg.received_at
            if age > ages.get(name, -math.inf):
                ages[name] = age

    def _state(self, now: float) -> dict[str, Any]:
        servo = self.servo.get(now)
        guard = self.guard.get(now)
        world = self.world.get(now)
        held = self.deadman.held
        return {
            "t": round(now - (self._t0 or now), 3),
            "overlay": view_state.overlay(self.contour.get(now), self._limits),
            "servo": view_state.servo_view(servo),
            "banner": view_state.zero_banner(servo, guard),
            "guard": None if guard is None else {"stage": guard.stage, "reason": guard.reason},
            "world": None if world is None else {"stage": world.stage, "message": world.message},
            "errors": [
                [
                    e[0],
                    *[
                        round(x * s, 3) if math.isfinite(x) else None
                        for x, s in zip(
                            e[1:], (1000.0, 1000.0, 1000.0, 180.0 / math.pi), strict=True
                        )
                    ],
                ]
                for e in list(self._errors)[-150:]
            ],
            "links": [
                view_state.link_view(name, self._link_age.pop(name, math.inf), reg.link_alive)
                for name, reg in self._links()
            ],
            "smart_alive": None  # nothing from the servo side yet (or none in this graph)
            if self.joints.value is None and self.guard.value is None
            else self.joints.link_alive and self.guard.link_alive,
            "joints": view_state.joints_view(self.joints.get(now), *self._q_limits),
            "control": self.arbiter.holder_name(),
            "control_session": self.arbiter.holder or "",
            "viewers": [name for name in self.arbiter.sessions.values()],
            "refused": self.counts["refused"],
            "jog": None
            if held is None
            else {"axes": held.axes, "frame": held.jog_frame, "speed": held.speed},
            "assist": self._assist,
            "zoom": [{"name": k, "value": round(v, 3)} for k, v in self._zoom.items()],
            "notices": list(self._notices),
            "links_extra": dict(self._server.links) if self._server is not None else {},
        }
