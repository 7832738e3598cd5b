"""A small public harness to unit-test a module the way the scheduler runs it.

    from umbra.runtime.harness import ModuleHarness
    from umbra.connectors.messages import Scalar

    with ModuleHarness("Gain", {"gain": 3.0}) as h:      # type name or class
        h.push("input", Scalar(value=2.0))
        h.step(dt=0.01)                                   # advance the sim clock, run step()
        assert h.output("output").value == 6.0

Inputs are pushed into the module's registers (stamped with the harness clock when unstamped);
every sample the module sends is kept per output (``outputs(name)``), the latest by ``output``.
"""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Any

import msgspec
import numpy as np
import pydantic

from umbra.connectors.errors import UserError
from umbra.connectors.frames import FrameTree
from umbra.connectors.messages import Message
from umbra.connectors.module import Module, ModuleContext
from umbra.connectors.params import validation_problems
from umbra.runtime.clock import SimClock
from umbra.runtime.registry import Registry


class ModuleHarness:
    """Builds one module from parameters and steps it on a sim clock."""

    def __init__(
        self,
        module_type: str | type[Module[Any]],
        params: dict[str, Any] | None = None,
        *,
        name: str = "module",
        frames: FrameTree | dict[str, np.ndarray] | None = None,
        seed: int = 0,
        output_dir: str | Path | None = None,
        registry: Registry | None = None,
        attended: bool = False,
    ) -> None:
        cls = (
            (registry or Registry()).require(module_type)
            if isinstance(module_type, str)
            else module_type
        )
        try:
            validated = cls.Params(**(params or {}))
        except pydantic.ValidationError as exc:
            problems = "; ".join(validation_problems(cls.Params, exc))
            raise UserError(f"bad parameters for {cls.type_name()}: {problems}") from None
        if isinstance(frames, dict):
            tree = FrameTree()
            for key, T in frames.items():
                parent, child = key.split("->")
                tree.add(parent.strip(), child.strip(), T)
            frames = tree
        if output_dir is None:
            self._tmp = tempfile.TemporaryDirectory(prefix="umbra-harness-")
            output_dir = self._tmp.name
        self.clock = SimClock()
        self.stop_request: tuple[str, int] | None = None
        context = ModuleContext(
            graph="harness",
            frames=frames or FrameTree(),
            output_dir=Path(output_dir),
            rng=np.random.default_rng(seed),
            clock="sim",
            request_stop=self._request_stop,
            attended=attended,
        )
        self.module = cls(name, validated, context)
        self.module.bind_ports(self.clock.now)
        self._sent: dict[str, list[Message]] = {n: [] for n in self.module.outputs}
        for out_name, port in self.module.outputs.items():
            port.sinks.append(self._keeper(out_name))
            port.connected = True  # the test stands in for the graph's consumers
        self._seq: dict[str, int] = {}
        self.started = False

    def _keeper(self, name: str) -> Any:
        def keep(sample: Message, now: float) -> None:
            self._sent[name].append(sample)

        return keep

    def _request_stop(self, reason: str, code: int) -> None:
        if self.stop_request is None:
            self.stop_request = (reason, code)

    @property
    def now(self) -> float:
        """The harness clock [s]."""
        return self.clock.now()

    def start(self) -> ModuleHarness:
        """Call the module's ``start`` (once: ``with ModuleHarness(...)`` already has; a second
        start would take what the module holds twice, a page server, a device)."""
        if self.started:
            raise RuntimeError(f"{self.module.name}: started twice (`with` starts the module)")
        self.module.start()
        self.started = True
        return self

    def push(self, input_name: str, sample: Message) -> Message:
        """Write ``sample`` into input ``input_name`` as if a producer had sent it now; a sample
        of a type the input does not take is refused (TypeError), as ``umbra check`` refuses
        such a connection."""
        if input_name not in self.module.registers:
            raise KeyError(
                f"{self.module.type_name()} has no input `{input_name}` "
                f"(inputs: {', '.join(self.module.registers)})"
            )
        wanted = type(self.module).input_decls(self.module.params)[input_name].msg_type
        if not isinstance(sample, wanted):
            raise TypeError(
                f"{self.module.type_name()} input `{input_name}` takes {wanted.__name__}, "
                f"found {type(sample).__name__}"
            )
        seq = self._seq.get(input_name, 0) + 1
        self._seq[input_name] = seq
        stamp = sample.stamp or self.now
        stamped = msgspec.structs.replace(
            sample, seq=seq, stamp=stamp, origin=sample.origin or stamp
        )
        register = self.module.registers[input_name]
        register.connected = True
        register.write(stamped, self.now)
        return stamped

    def step(self, dt: float = 0.0) -> dict[str, list[Message]]:
        """Advance the clock by ``dt`` [s], run ``step`` once; returns the samples it sent."""
        if not self.started:
            self.start()
        before = {n: len(v) for n, v in self._sent.items()}
        self.clock.wait_until(self.now + dt)
        self.module.origin_track.reset()
        self.module.step(self.now)
        for reg in self.module.registers.values():
            reg.fresh = False
        return {n: v[before[n] :] for n, v in self._sent.items() if len(v) > before[n]}

    def run(self, steps: int, dt: float) -> None:
        """``steps`` steps ``dt`` apart."""
        for _ in range(steps):
            self.step(dt)

    def output(self, name: str) -> Any:
        """The latest sample sent on output ``name`` (None when none)."""
        sent = self._sent[name]
        return sent[-1] if sent else None

    def outputs(self, name: str) -> list[Any]:
        """Every sample sent on output ``name`` so far."""
        return list(self._sent[name])

    def stop(self) -> None:
        """Call the module's ``stop`` (once)."""
        if self.started:
            self.started = False
            self.module.stop()

    def __enter__(self) -> ModuleHarness:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
