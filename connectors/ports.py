"""Typed ports: inputs are registers (latest value, never blocking), outputs fan samples out.

A module declares its ports as class attributes::

    class Gain(Module):
        input = Input(Scalar, trigger=True, doc="value to scale")
        output = Output(Scalar, doc="scaled value")

Frames and joint names may be literal (``frame="camera"``) or taken from a parameter of the module
instance (``frame=from_param("camera_frame")``), so one module type serves several frames.

Freshness: every sample carries ``origin``, the capture time of the oldest sensor data behind it.
The runtime sets it: a sample sent during ``step`` takes the oldest origin of the inputs the
module read in that step (``get`` or ``value``; an event input counts only when it brought a new
event), or its own stamp when it read none. An output may narrow that: ``origin_from=("image",)``
takes the origin of the latest sample on those inputs only (vsSnake's contour: the image it
converged on; a jog: the image the operator's page shows), and ``measured=True`` marks a sensor
(joint encoders, a camera, the simulated plant) whose samples start a new origin at their stamp,
which is what makes origins advance around a control loop. A module may also set ``origin`` on
the sample it sends. ``umbra check`` follows the same declarations to bound origin ages.

Streams are of two kinds, declared on the output: state (the default: images, contours, poses,
joint states, statuses, twists) is latest-only end to end — a slow consumer gets the newest
sample and the superseded ones are counted, never queued; ``events=True`` (operator actions,
gripper commands, paths) is ordered and lossless.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

import msgspec

from umbra.connectors.messages import Message

M = TypeVar("M", bound=Message)


@dataclass(frozen=True)
class ParamRef:
    """A port attribute (frame or joint names) taken from the module's parameter ``name``."""

    name: str


def from_param(name: str) -> ParamRef:
    """Declare that a port's frame or joint names come from the module parameter ``name``."""
    return ParamRef(name)


FrameSpec = str | ParamRef | None
JointsSpec = tuple[str, ...] | ParamRef | None


class OriginTrack:
    """The oldest origin [s] among the inputs a module read in the current step (``inf``: none)."""

    __slots__ = ("oldest",)

    def __init__(self) -> None:
        self.oldest = float("inf")

    def reset(self) -> None:
        """Start a step: nothing read yet."""
        self.oldest = float("inf")


class _PortDecl:
    """Common part of :class:`Input` and :class:`Output` declarations."""

    kind = ""

    def __init__(self, msg_type: type[Message], frame: FrameSpec, joints: JointsSpec, doc: str):
        if not (isinstance(msg_type, type) and issubclass(msg_type, Message)):
            raise TypeError(f"port type must be a Message subclass, found {msg_type!r}")
        self.msg_type = msg_type
        self.frame = frame
        self.joints = tuple(joints) if isinstance(joints, list | tuple) else joints
        self.doc = doc
        self.name = ""

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    def resolve_frame(self, params: Any) -> str | None:
        """The port's frame for a module built with ``params`` (None: any / not frame-bearing)."""
        if isinstance(self.frame, ParamRef):
            value = getattr(params, self.frame.name)
            return None if value in (None, "") else str(value)
        return self.frame

    def resolve_joints(self, params: Any) -> tuple[str, ...] | None:
        """The joint names for a module built with ``params`` (None: not declared)."""
        if isinstance(self.joints, ParamRef):
            value = getattr(params, self.joints.name)
            return None if value is None else tuple(str(v) for v in value)
        return self.joints

    def describe_frame(self) -> str:
        if isinstance(self.frame, ParamRef):
            return f"<param {self.frame.name}>"
        return self.frame or ""


class Input(_PortDecl):
    """An input port declaration.

    ``trigger``: the module runs when a new sample arrives here. ``required``: the graph must
    connect it. ``max_age`` [s]: samples older than this (since they arrived) are not delivered and
    are counted as violations. ``feedback``: carries measured plant state (joint angles, camera
    pose), not a command; guard checks do not follow it. ``requires_guard``: every command path
    feeding this input must pass through a safety-guard module (a watchdog register).
    ``max_origin_age`` [s] (a number or ``from_param``): the oldest origin the module accepts on
    this input (it refuses older commands itself, in its own words); ``umbra check`` computes the
    worst origin age the graph's rates allow on every path into it and refuses a graph that
    cannot meet the bound.
    """

    kind = "input"

    def __init__(
        self,
        msg_type: type[Message],
        *,
        frame: FrameSpec = None,
        joints: JointsSpec = None,
        trigger: bool = False,
        required: bool = True,
        max_age: float | None = None,
        feedback: bool = False,
        requires_guard: bool = False,
        max_origin_age: float | ParamRef | None = None,
        doc: str = "",
    ) -> None:
        super().__init__(msg_type, frame, joints, doc)
        self.trigger = trigger
        self.required = required
        self.max_age = max_age
        self.feedback = feedback
        self.requires_guard = requires_guard
        self.max_origin_age = max_origin_age

    def resolve_max_origin_age(self, params: Any) -> float | None:
        """The origin bound [s] for a module built with ``params`` (None: not declared)."""
        if isinstance(self.max_origin_age, ParamRef):
            value = getattr(params, self.max_origin_age.name)
            return None if value is None else float(value)
        return self.max_origin_age

    def __get__(self, instance: Any, owner: type | None = None) -> Any:
        if instance is None:
            return self
        return instance._registers[self.name]


class Output(_PortDecl):
    """An output port declaration; at run time ``self.<name>.send(msg)`` publishes a sample.

    ``events``: an ordered, lossless stream (operator actions, gripper commands, paths): every
    sample reaches every consumer, in order. Otherwise a state stream, latest-only.
    ``measured``: a sensor's output (a measurement of the plant at its stamp): its origin is its
    stamp, whatever the module read to make it. ``origin_from``: the inputs whose latest samples
    date this output (the oldest of them; ``-inf``, undatable, while none has a sample).
    """

    kind = "output"

    def __init__(
        self,
        msg_type: type[Message],
        *,
        frame: FrameSpec = None,
        joints: JointsSpec = None,
        events: bool = False,
        measured: bool = False,
        origin_from: tuple[str, ...] | None = None,
        doc: str = "",
    ) -> None:
        super().__init__(msg_type, frame, joints, doc)
        if measured and origin_from:
            raise TypeError("a measured output starts its own origin: no `origin_from`")
        self.events = events
        self.measured = measured
        #: None: the inputs read in the step; (): none (measured); else these inputs' latest
        self.origin_from: tuple[str, ...] | None = () if measured else origin_from

    def __get__(self, instance: Any, owner: type | None = None) -> Any:
        if instance is None:
            return self
        return instance._outputs[self.name]


class Register(Generic[M]):
    """The latest sample on an input, its arrival time, and whether it is new since the last step.

    Reading never blocks. ``get(now)`` returns the sample, or None when there is none yet or it is
    older than the input's ``max_age`` (then a violation is counted). Reading (``get`` or
    ``value``) enters the sample's origin into the module's :class:`OriginTrack`; on an event
    input only a new event (``fresh``) does.
    """

    __slots__ = (
        "_max_age",
        "_seen_alive",
        "_track",
        "_value",
        "clock_error",
        "clock_problem",
        "connected",
        "events",
        "fresh",
        "link_alive",
        "name",
        "received_at",
        "superseded",
        "violations",
    )

    def __init__(
        self, name: str, max_age: float | None = None, track: OriginTrack | None = None
    ) -> None:
        self.name = name
        self._value: M | None = None
        self.received_at = float("-inf")
        self.fresh = False
        self.violations = 0
        #: samples of a state stream replaced by a newer one before any step read them
        self.superseded = 0
        #: True when fed by an events output (ordered, lossless)
        self.events = False
        #: True when the graph wires an output to this input (set by the runtime as it wires
        #: the graph; by the harness at the first push): a module can tell "nothing yet" from
        #: "nothing will come"
        self.connected = False
        #: False while the producer is in another process not known to be alive (not yet seen,
        #: or gone): set by the runtime through :meth:`set_link_alive`
        self.link_alive = True
        self._seen_alive = False
        #: bound [s] on the error of the samples' stamps and origins on this process's clock (0:
        #: the same process; a link's: its measured offset's, inf until it is measured)
        self.clock_error = 0.0
        #: why the samples cannot be dated on this process's clock now (empty: they can, or the
        #: producer is in this process): set by the runtime with ``clock_error``
        self.clock_problem = ""
        self._max_age = max_age
        self._track = track

    def set_link_alive(self, alive: bool) -> None:
        """The runtime's word on the producer's process (its liveliness, a link's end)."""
        self.link_alive = alive
        self._seen_alive = self._seen_alive or alive

    @property
    def link_gone(self) -> bool:
        """True once the producer's process was seen alive and is no longer: gone, not merely
        not yet known (at start a sample may come before its producer's liveliness token)."""
        return self._seen_alive and not self.link_alive

    @property
    def value(self) -> M | None:
        """The latest sample (None when none arrived); reading it counts as reading the input."""
        sample = self._value
        if sample is not None:
            track = self._track
            if (
                track is not None
                and sample.origin < track.oldest
                and (self.fresh or not self.events)
            ):
                track.oldest = sample.origin
        return sample

    @value.setter
    def value(self, sample: M | None) -> None:
        self._value = sample

    def write(self, sample: M, now: float) -> None:
        """Store ``sample`` as the latest value, received at ``now`` [s]."""
        self._value = sample
        self.received_at = now
        self.fresh = True

    def age(self, now: float) -> float:
        """Seconds since the latest sample arrived (infinite when none has)."""
        return now - self.received_at

    def origin_age(self, now: float) -> float:
        """Seconds since the capture of the oldest sensor data behind the latest sample (infinite
        when there is none, or it cannot be dated)."""
        sample = self._value
        return float("inf") if sample is None else now - sample.origin

    def get(self, now: float) -> M | None:
        """The latest sample, or None when none arrived or it is older than ``max_age``."""
        if self._value is None:
            return None
        if self._max_age is not None and now - self.received_at > self._max_age:
            self.violations += 1
            return None
        return self.value

    @property
    def seq(self) -> int:
        """Sequence number of the latest sample (-1 when none)."""
        return -1 if self._value is None else self._value.seq


Sink = Callable[[Message, float], None]


class OutputPort:
    """A bound output: stamps each sample with a sequence number, a time (when unset) and an
    origin (when unset: see the module docstring), and hands it to every connected sink (input
    registers, delayed writers, link publishers)."""

    __slots__ = (
        "_clock",
        "_dated_by",
        "_seq",
        "_track",
        "connected",
        "events",
        "last",
        "msg_type",
        "name",
        "sinks",
    )

    def __init__(
        self,
        name: str,
        msg_type: type[Message],
        clock: Callable[[], float],
        track: OriginTrack | None = None,
        *,
        events: bool = False,
        dated_by: list[Register[Any]] | None = None,
    ) -> None:
        """``dated_by``: the registers whose latest samples date this output (``[]``: a
        measurement, dated by its own stamp; None: the inputs read in the step, ``track``)."""
        self.name = name
        self.msg_type = msg_type
        self.sinks: list[Sink] = []
        #: True when the graph wires this output to an input (set by the runtime as it wires the
        #: graph; by the harness, whose test stands in for the consumers). A recording or a live
        #: viewer adds sinks too, but is nobody the module may count on to act.
        self.connected = False
        self.last: Message | None = None
        self.events = events
        self._seq = 0
        self._clock = clock
        self._track = track
        self._dated_by = dated_by

    def _origin(self, stamp: float) -> float:
        """The origin of a sample stamped ``stamp`` whose module set none (module docstring)."""
        dated_by = self._dated_by
        if dated_by is None:
            track = self._track
            return track.oldest if track is not None and track.oldest < stamp else stamp
        if not dated_by:
            return stamp
        oldest = math.inf
        for reg in dated_by:
            sample = reg._value
            if sample is not None and sample.origin < oldest:
                oldest = sample.origin
        return -math.inf if oldest == math.inf else min(oldest, stamp)

    def send(self, msg: Message) -> Message:
        """Publish ``msg``; returns the stamped sample (``msg.stamp`` and ``msg.origin`` kept when
        non-zero)."""
        if type(msg) is not self.msg_type and not isinstance(msg, self.msg_type):
            raise TypeError(
                f"output `{self.name}` carries {self.msg_type.__name__}, "
                f"was sent {type(msg).__name__}"
            )
        now = self._clock()
        self._seq += 1
        stamp = msg.stamp if msg.stamp else now
        origin = msg.origin or self._origin(stamp)
        sample = msgspec.structs.replace(msg, seq=self._seq, stamp=stamp, origin=origin)
        self.last = sample
        for sink in self.sinks:
            sink(sample, now)
        return sample

    @property
    def count(self) -> int:
        """Samples sent so far."""
        return self._seq
