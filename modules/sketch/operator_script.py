"""SketchOperatorSim: a scripted operator for Active Sketch runs without a person at the console."""

from __future__ import annotations

import math

import numpy as np
from pydantic import field_validator

from umbra.connectors import Input, Module, Output, Parameters, UserError, param
from umbra.connectors.messages import Status, Text
from umbra.connectors.path_messages import VcrMode, VcrState
from umbra.connectors.ptu_messages import PtuState
from umbra.connectors.scene_messages import SceneObjects
from umbra.connectors.sketch_messages import SketchPrimitive, SketchReply, StereoSnapshot
from umbra.modules.sketch.command_text import VERBS, parse
from umbra.modules.sketch.primitives import KINDS
from umbra.modules.sketch.stereo import StereoPair
from umbra.modules.world.scene_objects import targets_from_objects

_OWN = ("wait", "settle", "wait_vcr")
#: Longest ``wait S`` step [s].
MAX_WAIT_S = 3600.0
#: Snapshots refused right after ``settle`` that the script settles again for and retakes.
SNAPSHOT_RETRIES = 3


def script_step_problem(step: str) -> str:
    """Why ``step`` is not a step the scripted operator can play; empty when it is. Sketch
    commands are parsed as the Sketch module parses them, with ``@feature`` standing for a point
    and ``@last`` for a primitive's id (their values are known only while the run goes)."""
    words = step.split()
    expected = f"expected one of {', '.join(VERBS + _OWN)}"
    if not words or words[0] not in VERBS + _OWN:
        return f"not a command; {expected}"
    verb, rest = words[0], words[1:]
    if verb == "wait":
        try:
            seconds = float(rest[0]) if len(rest) == 1 else math.nan
        except ValueError:
            seconds = math.nan
        if not 0.0 <= seconds <= MAX_WAIT_S:
            return f"expected `wait S` with 0 <= S <= {MAX_WAIT_S:g} seconds"
        return ""
    if verb == "settle":
        return "" if not rest else "expected `settle` alone"
    if verb == "wait_vcr":
        if len(rest) != 1 or rest[0] not in set(VcrMode):
            return f"expected `wait_vcr MODE` with MODE one of {VcrMode.listed()}"
        return ""
    if verb == "place" and len(rest) == 2 and rest[1].startswith("@"):
        return (
            ""
            if rest[0] in KINDS
            else f"expected `place KIND @feature`, KIND one of {', '.join(KINDS)}"
        )
    stand_in = []
    for w in words:
        if w == "@last":
            stand_in.append("p1")
        elif w.startswith("@"):
            stand_in.append("0 0 0")
        else:
            stand_in.append(w)
    try:
        parse(" ".join(stand_in))
    except UserError as exc:
        return str(exc).replace(f"sketch command {' '.join(stand_in)!r}: ", "")
    return ""


class SketchOperatorSim(Module["SketchOperatorSim.Params"]):
    """Plays an operator's script against the Sketch module, one step at a time.

    Steps are Sketch commands (``modules/sketch/command_text.py``) in which ``@name`` stands for a
    true scene feature (``umbra.modules.world.scene_objects.targets_from_objects``: ``@pipe``,
    ``@handle``, ``@hinge``, ``@surface``, ``@package_edge``, ``@pipe_center``, ...) and
    ``@last`` for the last placed primitive; ``place KIND @feature`` clicks the feature's true
    image points in the last snapshot with ``click_noise_px`` of noise (the right-hand clicks
    also ``off_line_px`` off the epipolar line; the Sketch module puts them back on it). Own steps:
    ``wait S`` (seconds), ``settle`` (until both PTUs stop, then ``settle_s``), ``wait_vcr MODE``
    (until the player reports MODE; a halt on the way is met as an operator would: after
    ``resume_after_halt_s`` it presses play, or back, again). A command the Sketch module refuses
    ends the run (exit 1). In an attended run (``ModuleContext.attended``) it plays nothing: the
    person at the page is the operator.
    """

    TYPE = "SketchOperatorSim"

    class Params(Parameters):
        script: list[str] = param([], "the steps, in order")
        click_noise_px: float = param(0.5, "click noise (sigma)", unit="px", ge=0, le=20)
        off_line_px: float = param(6.0, "right-hand clicks off the epipolar line", unit="px")
        settle_s: float = param(0.5, "after the PTUs stop, wait for fresh images", unit="s", ge=0)
        end_when_done: bool = param(False, "end the run (exit 0) after the last step")
        resume_after_halt_s: float = param(
            1.0, "wait_vcr: after the player halts, press play again after", unit="s", gt=0
        )

        @field_validator("script")
        @classmethod
        def _steps(cls, script: list[str]) -> list[str]:
            for i, step in enumerate(script):
                problem = script_step_problem(step)
                if problem:
                    raise ValueError(f"script step {i + 1} {step!r}: {problem}")
            return script

    objects = Input(SceneObjects, feedback=True, doc="the scene's truth (SketchWorld)")
    snapshot = Input(StereoSnapshot, required=False, doc="snapshots taken (Sketch)")
    primitive = Input(SketchPrimitive, required=False, doc="primitives placed (Sketch)")
    sketch_status = Input(Status, required=False, doc="Sketch's reply to each command")
    vcr_state = Input(VcrState, required=False, feedback=True, doc="the player's state")
    ptu_a = Input(PtuState, required=False, feedback=True, doc="PTU a state")
    ptu_b = Input(PtuState, required=False, feedback=True, doc="PTU b state")
    command = Output(Text, events=True, doc="commands for Sketch")

    def start(self) -> None:
        self._index = 0
        self._waiting_reply = False
        self._until: float | None = None
        self._still_since: float | None = None
        self._done = False
        self._halted_since: float | None = None
        self._direction = "play"
        self._resumes = 0
        self._sent: int | None = None  # the script step whose command awaits Sketch's reply
        self._snapshot_retries = 0
        if self.context.attended:
            self.log.info("attended run: the scripted operator stays off (a person sketches)")

    def step(self, now: float) -> None:
        if self.context.attended:
            return
        reply = self.sketch_status.get(now)
        if self._waiting_reply:
            if reply is None or not self.sketch_status.fresh:
                return
            self._waiting_reply = False
            if reply.stage == SketchReply.REFUSED:
                if self._settle_again():
                    self.log.info("sketch refused the snapshot (%s): settling again", reply.message)
                    return
                self.context.request_stop(f"operator script: refused: {reply.message}", 1)
                self._index, self._done = len(self.params.script), True  # plays nothing more
                return
            self.log.info("sketch: %s", reply.message)
        if self._index >= len(self.params.script):
            if not self._done:
                self._done = True
                if self.params.end_when_done:
                    self.context.request_stop("operator script finished", 0)
            return
        step = self.params.script[self._index]
        words = step.split()
        if words[0] == "wait":
            if self._until is None:
                self._until = now + float(words[1])
            if now < self._until:
                return
            self._until = None
        elif words[0] == "settle":
            a, b = self.ptu_a.get(now), self.ptu_b.get(now)
            still = a is not None and b is not None and not a.moving and not b.moving
            if not still:
                self._still_since = None
                return
            self._still_since = self._still_since if self._still_since is not None else now
            if now - self._still_since < self.params.settle_s:
                return
            self._still_since = None
        elif words[0] == "wait_vcr":
            state = self.vcr_state.get(now)
            if state is not None and state.mode == VcrMode.HALTED and words[1] != VcrMode.HALTED:
                self._resume_after_halt(state.reason, now)
                return
            self._halted_since = None
            if state is None or state.mode != words[1]:
                return
        else:
            text = self._expand(words, now)
            if text is None:
                return
            if words[0] == "vcr" and len(words) > 1 and words[1] in ("play", "resume", "back"):
                self._direction = "back" if words[1] == "back" else "play"
            self.command.send(Text(text=text))
            self._waiting_reply = True
            self._sent = self._index
        self._index += 1

    def _settle_again(self) -> bool:
        """What a person does when a snapshot right after ``settle`` is refused (a camera moved
        again: a PTU re-aims while its zoom camera still zooms): wait for the cameras to settle
        and take it again, at most ``SNAPSHOT_RETRIES`` times; False for any other refusal."""
        sent = self._sent
        script = self.params.script
        if sent is None or sent == 0 or script[sent].split()[0] != "snapshot":
            return False
        if script[sent - 1].split()[0] != "settle" or self._snapshot_retries >= SNAPSHOT_RETRIES:
            return False
        self._snapshot_retries += 1
        self._index = sent - 1
        return True

    def _resume_after_halt(self, reason: str, now: float) -> None:
        """What an operator does when the player halts (guard stop, stale state): wait, then
        press play (or back) again."""
        if self._halted_since is None:
            self._halted_since = now
            self.log.warning("operator: the player halted (%s)", reason)
            return
        if now - self._halted_since < self.params.resume_after_halt_s:
            return
        self._halted_since = None
        self._resumes += 1
        self.command.send(Text(text=f"vcr {self._direction}"))
        self._waiting_reply = True

    def _expand(self, words: list[str], now: float) -> str | None:
        objects = self.objects.get(now)
        if any(w.startswith("@") and w != "@last" for w in words) and objects is None:
            return None  # the truth has not arrived yet
        targets = targets_from_objects(objects) if objects is not None else {}
        if words[0] == "place" and len(words) == 3 and words[2].startswith("@"):
            return self._clicks(words[1], targets[words[2][1:]], now)
        out = []
        for w in words:
            if w == "@last":
                prim = self.primitive.get(now)
                if prim is None:
                    raise UserError("operator script: @last before any primitive was placed")
                out.append(prim.primitive_id)
            elif w.startswith("@"):
                out.append(" ".join(f"{x:.6f}" for x in np.asarray(targets[w[1:]]).reshape(-1)[:3]))
            else:
                out.append(w)
        return " ".join(out)

    def _clicks(self, kind: str, points: np.ndarray, now: float) -> str | None:
        snap = self.snapshot.get(now)
        if snap is None:
            return None
        pair = StereoPair.from_snapshot(snap)
        rng = self.context.rng
        sigma = self.params.click_noise_px
        a = pair.project("a", points) + rng.normal(0.0, sigma, (len(points), 2))
        b = pair.project("b", points)
        normal = pair.epipolar_line_b(a)[:, :2]
        along = normal @ np.array([[0.0, 1.0], [-1.0, 0.0]])
        b = b + self.params.off_line_px * normal + rng.normal(0.0, sigma, (len(points), 1)) * along
        fmt = " ".join
        return (
            f"place {kind} {fmt(f'{u:.3f},{v:.3f}' for u, v in a)} | "
            f"{fmt(f'{u:.3f},{v:.3f}' for u, v in b)}"
        )

    def summary(self) -> dict[str, object]:
        return {
            "steps_done": self._index,
            "resumes_after_halt": self._resumes,
            "attended": self.context.attended,
        }
