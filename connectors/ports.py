"""Typed ports: inputs are registers (latest value, never blocking), outputs fan samples out.

A module declares its ports as class attributes::

    class Gain(Module):
        input = Input(Scalar, trigger=True, doc="value to scale")
        output = Output(Scalar, doc="scaled value")

Frames and joint names may be literal (``frame="camera"``) or taken from a parameter of the module
instance (``frame=from_param("camera_frame")``), so one module type serves several frames.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

import msgspec

from connectors.messages import Message

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
        doc: str = "",
    ) -> None:
        super().__init__(msg_type, frame, joints, doc)
        self.trigger = trigger
        self.required = required
        self.max_age = max_age
        self.feedback = feedback
        self.requires_guard = requires_guard

    def __get__(self, instance: Any, owner: type | None = None) -> Any:
        if instance is None:
            return self
        return instance._registers[self.name]


class Output(_PortDecl):
    """An output port declaration; at run time ``self.<name>.send(msg)`` publishes a sample."""

    kind = "output"

    def __init__(
        self,
        msg_type: type[Message],
        *,
        frame: FrameSpec = None,
        joints: JointsSpec = None,
        doc: str = "",
    ) -> None:
        super().__init__(msg_type, frame, joints, doc)

    def __get__(self, instance: Any, owner: type | None = None) -> Any:
        if instance is None:
            return self
        return instance._outputs[self.name]


class Register(Generic[M]):
    """The latest sample on an input, its arrival time, and whether it is new since the last step.

    Reading never blocks. ``get(now)`` returns the sample, or None when there is none yet or it is
    older than the input's ``max_age`` (then a violation is counted).
    """

    __slots__ = ("_max_age", "fresh", "link_alive", "name", "received_at", "value", "violations")

    def __init__(self, name: str, max_age: float | None = None) -> None:
        self.name = name
        self.value: M | None = None
        self.received_at = float("-inf")
        self.fresh = False
        self.violations = 0
        #: False when the producer is in another process that is known to be gone.
        self.link_alive = True
        self._max_age = max_age

    def write(self, sample: M, now: float) -> None:
        """Store ``sample`` as the latest value, received at ``now`` [s]."""
        self.value = sample
        self.received_at = now
        self.fresh = True

    def age(self, now: float) -> float:
        """Seconds since the latest sample arrived (infinite when none has)."""
        return now - self.received_at

    def get(self, now: float) -> M | None:
        """The latest sample, or None when none arrived or it is older than ``max_age``."""
        if self.value is None:
            return None
        if self._max_age is not None and now - self.received_at > self._max_age:
            self.violations += 1
            return None
        return self.value

    @property
    def seq(self) -> int:
        """Sequence number of the latest sample (-1 when none)."""
        return -1 if self.value is None else self.value.seq


Sink = Callable[[Message, float], None]


class OutputPort:
    """A bound output: stamps each sample with a sequence number (and time, when unset) and hands
    it to every connected sink (input registers, delayed writers, link publishers)."""

    __slots__ = ("_clock", "_seq", "last", "msg_type", "name", "sinks")

    def __init__(self, name: str, msg_type: type[Message], clock: Callable[[], float]) -> None:
        self.name = name
        self.msg_type = msg_type
        self.sinks: list[Sink] = []
        self.last: Message | None = None
        self._seq = 0
        self._clock = clock

    def send(self, msg: Message) -> Message:
        """Publish ``msg``; returns the stamped sample (``msg.stamp`` kept when non-zero)."""
        if type(msg) is not self.msg_type and not isinstance(msg, self.msg_type):
            raise TypeError(
                f"output `{self.name}` carries {self.msg_type.__name__}, "
                f"was sent {type(msg).__name__}"
            )
        now = self._clock()
        self._seq += 1
        stamp = msg.stamp if msg.stamp else now
        sample = msgspec.structs.replace(msg, seq=self._seq, stamp=stamp)
        self.last = sample
        for sink in self.sinks:
            sink(sample, now)
        return sample

    @property
    def count(self) -> int:
        """Samples sent so far."""
        return self._seq
