"""Tunable parameters changed while a process runs: checked on arrival, applied between steps.

A change (``umbra.connectors.messages.ParamChange``: module, parameter, JSON value, who asked)
reaches the process that runs the module, from its own live server or over the run's parameter link
(``umbra.runtime.live.param_link``). It is checked once, where it comes in (:func:`checked`: the
parameter is declared tunable, the value passes the module's parameter model exactly as ``--set``
does: :func:`umbra.connectors.params.with_change`): by :meth:`Tuner.request` for a change from
another process, by the live server's table for a viewer's change to a module of this process (which
hands it on with :meth:`Tuner.queue_checked`). The scheduler calls :meth:`apply` at the start of
a tick, before any module steps, so a step never sees its parameters change under it. Applied,
the value is set into the parameters of that moment (the model builds them: a change to another
parameter since may have made it inconsistent), the module's ``retune`` rebuilds what it
derived, and the change is logged
(``param snake.tension 0.1 -> 0.2 by foxglove viewer #1 (127.0.0.1)``) and recorded when the
run records (``/umbra/param_changes``, ``ParamChange`` with ``old`` set). A module whose
``retune`` raises all the same (a defect: its model took the value) keeps its old parameters,
the log says why, and the run goes on.
"""

from __future__ import annotations

import logging
import threading
from collections import deque
from collections.abc import Callable
from typing import Any

from umbra.connectors.cli_support import parse_value
from umbra.connectors.errors import UserError
from umbra.connectors.json_text import json_text
from umbra.connectors.messages import ParamChange
from umbra.connectors.module import Module
from umbra.connectors.params import Parameters, is_safety, is_tunable, with_change

#: The recording's topic of applied changes.
CHANGES_TOPIC = "/umbra/param_changes"
#: Changes waiting for the next tick at most (more: refused, the viewer is told).
MAX_PENDING = 64


def tunable_problem(module_cls: type[Module[Any]], module: str, name: str) -> str:
    """Why ``module.name`` may not be changed live; empty when it may."""
    params = module_cls.Params
    if name not in params.model_fields:
        known = ", ".join(params.model_fields) or "none"
        kind = module_cls.type_name()
        return f"`{module}` ({kind}) has no parameter `{name}` (parameters: {known})"
    if module_cls.SAFETY_GUARD:
        return (
            f"`{module}.{name}` is a parameter of a safety guard ({module_cls.type_name()}): "
            "never changed while the graph runs"
        )
    if is_safety(params, name):
        return f"`{module}.{name}` is a safety parameter: never changed while the graph runs"
    if not is_tunable(params, name):
        tunable = [n for n in params.model_fields if is_tunable(params, n)]
        which = ", ".join(tunable) if tunable else "none"
        return f"`{module}.{name}` is not declared tunable (tunable in {module}: {which})"
    return ""


def checked(
    module_cls: type[Module[Any]], module: str, params: Parameters, name: str, value: Any
) -> tuple[Parameters, Any]:
    """``params`` of ``module`` with ``name`` = ``value``, and the value as read (text read as
    ``--set`` reads it); ``ValueError`` saying what was expected and what was found."""
    why = tunable_problem(module_cls, module, name)
    if why:
        raise ValueError(why)
    if isinstance(value, str):
        try:
            value = parse_value(value, f"{module}.{name}")
        except UserError as exc:
            raise ValueError(str(exc)) from None
    return with_change(params, name, value), value


def as_json(value: Any) -> str:
    """A parameter's value as JSON text (a change's record, a viewer's parameter list)."""
    return json_text(value, default=str)


class Tuner:
    """The live changes of one process's modules (see the module docstring)."""

    def __init__(
        self,
        modules: dict[str, Module[Any]],
        log: logging.Logger | None = None,
    ) -> None:
        self._modules = modules
        self._log = log or logging.getLogger("umbra")
        #: ``(change, now)`` for each applied change, set when the run records
        self.record: Callable[[ParamChange, float], Any] | None = None
        self._pending: deque[tuple[str, str, Any, str]] = deque()
        self._lock = threading.Lock()

    def request(self, module: str, name: str, value: Any, by: str) -> str:
        """Check ``module.name = value`` (:func:`checked`) and queue it for the next tick; the
        reason when refused (empty: queued). Any thread."""
        instance = self._modules.get(module)
        if instance is None:
            why = f"no module `{module}` runs in this process"
            return self._refused(module, name, value, by, why)
        try:
            _new, value = checked(type(instance), module, instance.params, name, value)
        except ValueError as exc:
            return self._refused(module, name, value, by, str(exc))
        return self.queue_checked(module, name, value, by)

    def queue_checked(self, module: str, name: str, value: Any, by: str) -> str:
        """Queue a change of a module of this process that its caller has passed through
        :func:`checked` (``value`` as it read it); the reason when refused (empty: queued)."""
        with self._lock:
            full = len(self._pending) >= MAX_PENDING
            if not full:
                self._pending.append((module, name, value, by))
        if full:
            why = f"{MAX_PENDING} changes already wait for the next tick"
            return self._refused(module, name, value, by, why)
        return ""

    def _refused(self, module: str, name: str, value: Any, by: str, why: str) -> str:
        self._log.warning("param %s.%s = %r by %s refused: %s", module, name, value, by, why)
        return why

    @property
    def pending(self) -> bool:
        return bool(self._pending)

    def apply(self, now: float) -> None:
        """Apply the queued changes (the scheduler's thread, before the tick's first step)."""
        with self._lock:
            todo = list(self._pending)
            self._pending.clear()
        for module, name, value, by in todo:
            instance = self._modules[module]
            old = instance.params
            try:
                new = with_change(old, name, value)
            except ValueError as exc:
                self._log.warning("param %s.%s by %s refused: %s", module, name, by, exc)
                continue
            instance.params = new
            why = _retuned(instance, old, new)
            if why:
                self._log.error(
                    "param %s.%s by %s refused and rolled back: %s", module, name, by, why
                )
                continue
            before, after = as_json(getattr(old, name)), as_json(getattr(new, name))
            self._log.info("param %s.%s %s -> %s by %s", module, name, before, after, by)
            change = ParamChange(
                module=module, param=name, value=after, old=before, by=by, stamp=now
            )
            if self.record is not None:
                self.record(change, now)


def _retuned(instance: Module[Any], old: Parameters, new: Parameters) -> str:
    """Apply ``new`` (already in ``instance.params``) through the module's ``retune``; empty when
    it took them. A module that fails on validated parameters is a defect of that module, never
    a reason to end the run: its parameters go back to ``old`` and it is retuned to them."""
    try:
        instance.retune(old)
        return ""
    except Exception as exc:
        why = f"{type(instance).type_name()} `{instance.name}` could not take it: {exc!r}"
    instance.params = old
    try:
        instance.retune(new)
    except Exception as exc:
        why += f" (and failed again going back: {exc!r})"
    return why
