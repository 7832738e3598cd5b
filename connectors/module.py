"""The module base class: declared ports and parameters, and a start / step / stop lifecycle.

A module type is a subclass with a registered type name, typed ports, declared parameters and
three methods. The declaration is the documentation: ``umbra describe TYPE`` prints it.

    class Gain(Module["Gain.Params"]):
        \"\"\"Scales a scalar.\"\"\"

        class Params(Parameters):
            gain: float = param(2.0, "factor", unit="1")

        input = Input(Scalar, trigger=True, doc="value to scale")
        output = Output(Scalar, doc="scaled value")

        def step(self, now: float) -> None:
            sample = self.input.get(now)
            if sample is not None:
                self.output.send(Scalar(value=self.params.gain * sample.value))

``Module`` is generic in its parameters: ``Module["Gain.Params"]`` names the class's own
``Params``, so ``self.params`` has that type for the type checker (a module without parameters of
its own writes ``Module[Parameters]``).

``step`` must never block: a device that blocks reads in its own thread and hands over its latest
value. Time comes from the scheduler's clock (``now``, seconds), never from ``time.time()``.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar, Generic, TypeVar

import numpy as np

from umbra.connectors.frames import FrameTree
from umbra.connectors.params import Parameters, is_tunable
from umbra.connectors.ports import Input, OriginTrack, Output, OutputPort, Register


@dataclass
class ModuleContext:
    """What the runtime gives a module instance besides its parameters.

    ``frames``: the graph's static frames. ``output_dir``: where the module may write files (videos,
    recordings). ``rng``: a random generator seeded from the graph seed and the module name, so a
    sim run is reproducible. ``clock``: "sim" or "real". ``request_stop(reason, exit_code)`` ends
    the run after the current tick (a simulated world that judged the grasp, a file that ended).
    Whether an input's producer (in another process) is alive: ``self.<input>.link_alive``.
    ``attended``: a person runs this run (``umbra run --attended``): simulated operators stay
    off, and judges publish their verdict but leave ending the run to the person (Ctrl-C):
    a judge ends the run through :meth:`end_run`, which holds that rule.
    """

    graph: str = "graph"
    frames: FrameTree = field(default_factory=FrameTree)
    output_dir: Path = field(default_factory=lambda: Path("."))
    rng: np.random.Generator = field(default_factory=lambda: np.random.default_rng(0))
    clock: str = "sim"
    log: logging.Logger = field(default_factory=lambda: logging.getLogger("umbra"))
    request_stop: Callable[[str, int], None] = field(default=lambda reason, code: None)
    process: str = "main"
    attended: bool = False
    _attended_said: bool = field(default=False, repr=False)

    def end_run(self, verdict: str, exit_code: int) -> bool:
        """A judge's ``verdict`` ends the run with ``exit_code`` (``request_stop``), unless the
        run is attended: then the person ends it, and the log says so once. True when the run
        was asked to end."""
        if not self.attended:
            self.request_stop(verdict, exit_code)
            return True
        if not self._attended_said:
            self._attended_said = True
            self.log.info(
                "attended run: %s; the run goes on until its operator stops it (Ctrl-C)", verdict
            )
        return False


#: A module's own parameter class.
P = TypeVar("P", bound=Parameters)


class Module(Generic[P]):
    """Base class of every module type. Subclasses declare ``Params``, ``Input``s, ``Output``s,
    and name their ``Params`` as the base's argument: ``class Gain(Module["Gain.Params"])``."""

    #: Registered type name (as in graphs); defaults to the class name.
    TYPE: ClassVar[str] = ""
    #: The module's parameter schema.
    Params: ClassVar[type[Parameters]] = Parameters
    #: True for safety guards (watchdog registers): command paths to guarded inputs must pass one.
    SAFETY_GUARD: ClassVar[bool] = False

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if cls.SAFETY_GUARD:
            tunable = [n for n in cls.Params.model_fields if is_tunable(cls.Params, n)]
            if tunable:
                raise TypeError(
                    f"{cls.__qualname__} is a safety guard: its parameter `{tunable[0]}` cannot be "
                    "tunable (every parameter of a guard bounds what reaches the arm)"
                )

    def __init__(self, name: str, params: P, context: ModuleContext | None = None):
        self.name = name
        self.params: P = params
        self.context = context or ModuleContext()
        self.log = self.context.log.getChild(name)
        self._registers: dict[str, Register[Any]] = {}
        self._outputs: dict[str, OutputPort] = {}
        #: the oldest origin read in the current step (reset by the runtime before each step)
        self.origin_track = OriginTrack()

    # -- declarations -------------------------------------------------------------------------
    @classmethod
    def type_name(cls) -> str:
        """The type name used in graphs."""
        return cls.TYPE or cls.__name__

    @classmethod
    def input_decls(cls, params: Parameters | None = None) -> dict[str, Input]:
        """Declared inputs in declaration order, plus ``dynamic_inputs(params)`` when given."""
        found = _collect(cls, Input)
        if params is not None:
            for name, decl in cls.dynamic_inputs(params).items():
                decl.name = name
                found[name] = decl
        return found

    @classmethod
    def dynamic_inputs(cls, params: Parameters) -> dict[str, Input]:
        """Inputs that depend on parameters (a recorder's channels); none by default."""
        return {}

    @classmethod
    def output_decls(cls) -> dict[str, Output]:
        """Declared outputs in declaration order."""
        return _collect(cls, Output)

    # -- lifecycle ------------------------------------------------------------------------------
    def start(self) -> None:
        """Acquire resources (open devices, files). Raise ``UserError`` for bad configuration."""

    def step(self, now: float) -> None:
        """Do one period's work at time ``now`` [s]; read inputs, send outputs; never block."""

    def stop(self) -> None:
        """Release resources; always called once the module has started, even after an error."""

    def retune(self, old: Parameters) -> None:
        """``self.params`` was changed while running (tunable parameters only, between two
        steps; ``old``: the parameters before): rebuild what ``start`` derived from them. Nothing
        by default (a module that reads ``self.params`` in ``step`` needs nothing)."""

    def summary(self) -> dict[str, Any]:
        """Figures for the end-of-run summary (counts, results); empty by default."""
        return {}

    def outcome_at_duration(self) -> tuple[int, str] | None:
        """When the run ends by its ``duration``: the exit status and reason this module gives
        it (a judge that has not judged yet: ``(1, "no verdict ...")``), or None to leave it 0."""
        return None

    # -- wiring (used by the runtime and the harness) -------------------------------------------
    def bind_ports(self, clock: Callable[[], float]) -> None:
        """Create this instance's input registers and output ports."""
        cls = type(self)
        track = self.origin_track
        for name, in_decl in self.input_decls(self.params).items():
            self._registers[name] = Register(name, in_decl.max_age, track)
            if isinstance(getattr(cls, name, None), Input):
                self.__dict__[name] = self._registers[name]  # plain lookup, no descriptor call
        for name, decl in self.output_decls().items():
            dated_by = (
                None
                if decl.origin_from is None
                else [self._registers[i] for i in decl.origin_from if i in self._registers]
            )
            self._outputs[name] = OutputPort(
                name, decl.msg_type, clock, track, events=decl.events, dated_by=dated_by
            )
            if isinstance(getattr(cls, name, None), Output):
                self.__dict__[name] = self._outputs[name]

    @property
    def registers(self) -> dict[str, Register[Any]]:
        """Input registers by port name."""
        return self._registers

    @property
    def outputs(self) -> dict[str, OutputPort]:
        """Output ports by port name."""
        return self._outputs


def _collect(cls: type, kind: type) -> dict[str, Any]:
    found: dict[str, Any] = {}
    for klass in reversed(cls.__mro__):
        for name, value in vars(klass).items():
            if isinstance(value, kind):
                found[name] = value
    return found
