"""The lens of a simulated FCB camera: zoom, focus with its auto/manual mode, and the six memories.

Pure state, no I/O: :class:`FcbLens` carries out the lens commands that
:mod:`umbra.modules.calib.visca.sim_logic` has given a socket, and says how long each runs. Times
are ``time.monotonic()`` seconds, positions raw FCB units.

Focus model (stated assumptions, not a Sony table): the focus position runs from
``FOCUS_RAW_FAR`` (infinity) to ``FOCUS_RAW_NEAR`` (closest) whatever the zoom, at the travel times
of :class:`~umbra.modules.calib.visca.zoom_motion.ZoomSpeeds` over that range. The simulated scene
is sharp at one focus position, ``af_raw``: in auto focus (the power-on mode) and after a one-push
trigger the focus runs there at the direct speed; far/near/direct move it only in manual focus.
A memory keeps the zoom position, the focus position and the focus mode at the time it was set;
recall runs zoom and focus back there at the direct speeds and completes when both arrived. A
memory never set, or reset, holds the power-on state (zoom ``initial_raw``, auto focus).
"""

from __future__ import annotations

from dataclasses import dataclass

from umbra.modules.calib.visca import commands as vc
from umbra.modules.calib.visca import commands_panel as cp
from umbra.modules.calib.visca.zoom_motion import Motion, ZoomSpeeds

FOCUS_RAW_FAR = 0x1000
"""Focus position at infinity (the far end)."""
FOCUS_RAW_NEAR = 0xF000
"""Focus position at the closest distance (the near end)."""
ZOOM, FOCUS = "zoom", "focus"
Axes = frozenset[str]

LensCommand = vc.ZoomStopCommand | vc.ZoomMoveCommand | vc.ZoomDirectCommand | cp.PanelSocketCommand


@dataclass(frozen=True)
class Preset:
    """What a memory holds: zoom and focus positions [raw] and the focus mode."""

    zoom_raw: int
    focus_raw: int
    focus_auto: bool


class FcbLens:
    """Zoom and focus motion, focus mode and memories of one simulated camera (see the module
    docstring). ``zoom_speeds`` / ``focus_speeds``: travel times over each range."""

    def __init__(
        self,
        zoom_speeds: ZoomSpeeds,
        focus_speeds: ZoomSpeeds,
        max_zoom_raw: int,
        initial_raw: int = 0,
        af_raw: int = 0x3000,
    ) -> None:
        if not FOCUS_RAW_FAR <= af_raw <= FOCUS_RAW_NEAR:
            raise ValueError(
                f"af_raw must be {FOCUS_RAW_FAR:#06x}..{FOCUS_RAW_NEAR:#06x}, got {af_raw:#06x}"
            )
        self.zoom_speeds, self.focus_speeds = zoom_speeds, focus_speeds
        self.max_zoom_raw = max_zoom_raw
        self.af_raw = af_raw
        self.zoom = Motion(initial_raw, initial_raw, 0.0, self._zoom_rate(zoom_speeds.direct_s))
        self.focus = Motion(af_raw, af_raw, 0.0, self._focus_rate(focus_speeds.direct_s))
        self.focus_auto = True
        self.power_on = Preset(initial_raw, af_raw, True)
        self.memories = [self.power_on] * cp.MEMORIES

    def _zoom_rate(self, full_range_s: float) -> float:
        return self.max_zoom_raw / full_range_s

    def _focus_rate(self, full_range_s: float) -> float:
        return (FOCUS_RAW_NEAR - FOCUS_RAW_FAR) / full_range_s

    # -- what a command touches --------------------------------------------------------------

    @staticmethod
    def axes(command: LensCommand) -> Axes:
        """The motions ``command`` takes over: a running command on one of them is cancelled."""
        if isinstance(command, vc.ZoomStopCommand | vc.ZoomMoveCommand | vc.ZoomDirectCommand):
            return frozenset((ZOOM,))
        if isinstance(command, cp.MemoryCommand):
            recall = command.action is cp.MemoryAction.RECALL
            return frozenset((ZOOM, FOCUS)) if recall else frozenset()
        return frozenset((FOCUS,))

    def not_executable(self, command: LensCommand) -> bool:
        """Manual focus control during auto focus (the camera answers "not executable")."""
        manual = cp.FocusMoveCommand | cp.FocusDirectCommand
        return self.focus_auto and isinstance(command, manual)

    # -- doing it ----------------------------------------------------------------------------

    def execute(self, command: LensCommand, now: float) -> float | None:
        """Carry out ``command`` at ``now``; the time it completes if it runs on (zoom direct,
        focus direct, memory recall: arrival), None if it completes at once."""
        if isinstance(command, vc.ZoomStopCommand | vc.ZoomMoveCommand | vc.ZoomDirectCommand):
            return self._zoom(command, now)
        if isinstance(command, cp.MemoryCommand):
            return self._memory(command, now)
        return self._focus(command, now)

    def halt(self, axes: Axes, now: float) -> None:
        """Hold the motions ``axes`` where they are at ``now`` (cancel, IF_Clear, power off)."""
        if ZOOM in axes:
            self.zoom = self.zoom.stopped(now)
        if FOCUS in axes:
            self.focus = self.focus.stopped(now)

    def _zoom(self, command: LensCommand, now: float) -> float | None:
        here = self.zoom.position(now)
        if isinstance(command, vc.ZoomDirectCommand):
            target = min(command.raw, self.max_zoom_raw)
            self.zoom = Motion(here, target, now, self._zoom_rate(self.zoom_speeds.direct_s))
            return self.zoom.arrival()
        if isinstance(command, vc.ZoomMoveCommand):
            end = self.max_zoom_raw if command.direction is vc.ZoomDirection.TELE else 0
            rate = self._zoom_rate(self.zoom_speeds.seconds(command.speed))
            self.zoom = Motion(here, end, now, rate)
        else:
            self.zoom = self.zoom.stopped(now)
        return None

    def _focus_to(self, target: int, now: float, full_range_s: float) -> None:
        here = self.focus.position(now)
        target = max(FOCUS_RAW_FAR, min(target, FOCUS_RAW_NEAR))
        self.focus = Motion(here, target, now, self._focus_rate(full_range_s))

    def _focus(self, command: LensCommand, now: float) -> float | None:
        direct_s = self.focus_speeds.direct_s
        if isinstance(command, cp.FocusModeCommand):
            toggled = command.mode is cp.FocusMode.TOGGLE
            self.focus_auto = not self.focus_auto if toggled else command.mode is cp.FocusMode.AUTO
            if self.focus_auto:
                self._focus_to(self.af_raw, now, direct_s)
            else:
                self.focus = self.focus.stopped(now)
        elif isinstance(command, cp.FocusOnePushCommand):
            self._focus_to(self.af_raw, now, direct_s)
        elif isinstance(command, cp.FocusMoveCommand):
            end = FOCUS_RAW_FAR if command.direction is cp.FocusDirection.FAR else FOCUS_RAW_NEAR
            self._focus_to(end, now, self.focus_speeds.seconds(command.speed))
        elif isinstance(command, cp.FocusDirectCommand):
            self._focus_to(command.raw, now, direct_s)
            return self.focus.arrival()
        elif not self.focus_auto:  # focus stop: in auto focus the AF keeps the focus
            self.focus = self.focus.stopped(now)
        return None

    def _memory(self, command: cp.MemoryCommand, now: float) -> float | None:
        if command.action is cp.MemoryAction.RESET:
            self.memories[command.number] = self.power_on
            return None
        if command.action is cp.MemoryAction.SET:
            self.memories[command.number] = Preset(
                self.zoom.position(now), self.focus.position(now), self.focus_auto
            )
            return None
        preset = self.memories[command.number]
        here = self.zoom.position(now)
        self.zoom = Motion(here, preset.zoom_raw, now, self._zoom_rate(self.zoom_speeds.direct_s))
        self.focus_auto = preset.focus_auto
        focus = self.af_raw if preset.focus_auto else preset.focus_raw
        self._focus_to(focus, now, self.focus_speeds.direct_s)
        return max(self.zoom.arrival(), self.focus.arrival())
