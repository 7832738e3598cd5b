"""The run's module parameters as a viewer sees them: ``MODULE.PARAM`` → value.

A viewer may read every parameter and change those a module declares tunable (never a safety
one: ``umbra.runtime.tuning.tunable_problem``). A change is checked here first (the parameter may be
tuned; the value passes the module's parameter model, as ``--set`` does), then handed to the
process that runs the module: this process's :class:`umbra.runtime.tuning.Tuner`, which takes it as
checked, or, for a module of another process, the run's parameter link
(``umbra.runtime.live.param_link``), where that process checks what arrives from the network
(``Tuner.request``). Either applies it between two steps. A refusal goes back to the viewer as a
message and into the run's log.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from umbra.runtime.tuning import as_json, checked

if TYPE_CHECKING:
    from umbra.runtime.graph.plan import GraphPlan
    from umbra.runtime.tuning import Tuner

#: ``(module, param, value, by)`` → why refused (empty: taken).
Sender = Callable[[str, str, Any, str], str]


def viewer_value(value: Any) -> Any:
    """A parameter value as the protocol carries it (numbers, strings, bools, lists of numbers;
    anything else as JSON text)."""
    if isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, (list, tuple)) and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) for v in value
    ):
        return [float(v) for v in value]
    return as_json(value)


class ParameterTable:
    """Every parameter of the run (``umbra.runtime.live.viewer_server.ParameterHandler``)."""

    def __init__(self, plan: GraphPlan, log: logging.Logger | None = None) -> None:
        self._plan = plan
        self._log = log or logging.getLogger("umbra.foxglove")
        #: the latest known parameters of each module (changed when a change is taken)
        self._params = {name: mplan.params for name, mplan in plan.modules.items()}
        self._senders: dict[str, Sender] = {}  #: module -> where its changes go

    def serve_locally(self, tuner: Tuner, modules: list[str]) -> None:
        """Changes of ``modules`` go to this process's ``tuner``, checked here (once)."""
        for module in modules:
            self._senders[module] = tuner.queue_checked

    def send_remotely(self, sender: Sender, modules: list[str]) -> None:
        """Changes of ``modules`` (run by other processes) go through ``sender``."""
        for module in modules:
            self._senders.setdefault(module, sender)

    def _all(self) -> dict[str, Any]:
        return {
            f"{module}.{key}": getattr(params, key)
            for module, params in self._params.items()
            for key in type(params).model_fields
        }

    def get(self, names: list[str]) -> list[dict[str, Any]]:
        values = self._all()
        wanted = names or list(values)
        return [{"name": n, "value": viewer_value(values[n])} for n in wanted if n in values]

    def set(
        self, viewer: str, changes: list[tuple[str, Any]]
    ) -> tuple[list[dict[str, Any]], list[str]]:
        answer, refusals = [], []
        for name, value in changes:
            why, taken = self._set_one(viewer, name, value)
            if why:
                refusals.append(f"parameter `{name}` not changed: {why}")
                self._log.warning(
                    "%s asked to set %s = %s: refused: %s",
                    viewer,
                    name,
                    as_json(value)[:200],
                    why,
                )
            current = self.get([name])
            answer.extend(current if why else [{"name": name, "value": viewer_value(taken)}])
        return answer, refusals

    def _set_one(self, viewer: str, name: str, value: Any) -> tuple[str, Any]:
        """``(why refused, value taken)``."""
        module, _, key = name.partition(".")
        mplan = self._plan.modules.get(module)
        if mplan is None or not key:
            return f"expected MODULE.PARAM of a module of the graph, found `{name}`", None
        try:
            changed, value = checked(mplan.cls, module, self._params[module], key, value)
        except ValueError as exc:
            return str(exc), None
        sender = self._senders.get(module)
        if sender is None:
            return (
                f"`{module}` runs in process `{mplan.process}`, which the live server does not "
                "reach (yet: it joins the run's processes once they are up)",
                None,
            )
        why = sender(module, key, value, viewer)
        if not why:
            self._params[module] = changed
        return why, getattr(changed, key)
