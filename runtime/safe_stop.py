"""Outputs in a safe state before anything stops: the last thing a loop does, whatever ended it.

Each module that defines ``safe_stop(now)`` has it called (in data order); each
``SAFETY_GUARD`` module without one has its numeric-array outputs (a twist, joint rates) sent
once more as zeros; then the modules those samples trigger run once so the zero reaches the
drives. Failures are logged, never raised: every module gets its turn.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any

import msgspec
import numpy as np

from umbra.connectors.messages import Message
from umbra.connectors.module import Module
from umbra.connectors.ports import OriginTrack, Register
from umbra.runtime.stats import ModuleStats


@dataclass
class Slot:
    """A module in the loop: its schedule (period and next due time [s]) and counters."""

    module: Module[Any]
    stats: ModuleStats
    period: float | None
    next_due: float
    k: int
    trigger_regs: list[Register[Any]]
    all_regs: list[Register[Any]]
    track: OriginTrack


def zeroed(sample: Message | None) -> Message | None:
    """``sample`` with every floating-point array zeroed and a fresh stamp, or None when it has
    no such array (text, status: nothing to zero, nothing re-sent)."""
    if sample is None:
        return None
    zeros = {
        name: np.zeros_like(value)
        for name in sample.__struct_fields__
        if isinstance(value := getattr(sample, name), np.ndarray) and value.dtype.kind in "fc"
    }
    if not zeros:
        return None
    return msgspec.structs.replace(sample, stamp=0.0, **zeros)


def safe_stop(started: list[Slot], now: float, log: logging.Logger | None = None) -> None:
    """Zero the commands of the ``started`` modules at ``now`` (s): ``safe_stop`` hooks, zeros
    from safety guards, then one pass of the modules those samples trigger."""
    log = log or logging.getLogger("umbra")
    sent = False
    for slot in started:
        module = slot.module
        hook = getattr(module, "safe_stop", None)
        try:
            slot.track.reset()
            if callable(hook):
                hook(now)
                sent = True
            elif module.SAFETY_GUARD:
                for port in module.outputs.values():
                    zero = zeroed(port.last)
                    if zero is not None:
                        port.send(zero)
                        sent = True
                        log.info("safe stop: `%s.%s` sent zero", module.name, port.name)
        except Exception as exc:
            log.error("safe stop of `%s` failed: %s: %s", module.name, type(exc).__name__, exc)
    if not sent:
        return
    for slot in started:
        if any(reg.fresh for reg in slot.trigger_regs):
            slot.track.reset()
            try:
                slot.module.step(now)
            except Exception as exc:
                log.error(
                    "safe stop: `%s` failed passing the zero on: %s: %s",
                    slot.module.name,
                    type(exc).__name__,
                    exc,
                )
            for reg in slot.all_regs:
                reg.fresh = False
