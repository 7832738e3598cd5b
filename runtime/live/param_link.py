"""Parameter changes from the live server to the process that runs the module, over zenoh.

In a split run the live server lives in the launcher's process, and a module runs in one of the
graph's processes. A change a viewer asks for, checked by the live server
(``umbra.runtime.live.parameters``), travels as a ``ParamChange`` on ``P/_params/<process>``
(``umbra.runtime.links.acl.param_key``):

- the launcher's process sends it as the run's *tuner* (``TUNER_USER``), a password the launcher
  makes only for a run served live; the graph-derived access rules let the tuner put on those
  keys and nothing else, and let nobody else put there (``umbra.runtime.links.acl``);
- each process subscribes to its own key only when its credentials say the run has a tuner
  (never with ``--insecure``, where anyone on the host could put), bounds what it decodes
  (``MAX_CHANGE_BYTES``, the ``ParamChange`` type), takes only changes of its own modules, and
  checks the change again (``umbra.runtime.tuning.Tuner.request``) before applying it between steps.
"""

from __future__ import annotations

import itertools
import json
import logging
import time
from typing import TYPE_CHECKING, Any

from umbra.connectors.codec import Codec
from umbra.connectors.messages import ParamChange
from umbra.runtime.links.acl import param_key

if TYPE_CHECKING:
    import zenoh

    from umbra.runtime.graph.plan import GraphPlan
    from umbra.runtime.tuning import Tuner

#: Largest parameter change a process decodes [bytes] (a value is at most a short list).
MAX_CHANGE_BYTES = 16 * 1024


class ParamSender:
    """The live server's side: one publisher per process (``send`` is a ``parameters.Sender``)."""

    def __init__(self, session: zenoh.Session, plan: GraphPlan) -> None:
        self._session = session
        self._plan = plan
        self._codec = Codec()
        self._seq = itertools.count(1)
        self._publishers = {
            p: session.declare_publisher(param_key(plan.key_prefix, p))
            for p in plan.populated_processes
        }

    def send(self, module: str, param: str, value: Any, by: str) -> str:
        process = self._plan.modules[module].process
        change = ParamChange(
            module=module,
            param=param,
            value=json.dumps(value),
            by=by,
            seq=next(self._seq),
            stamp=time.monotonic(),
        )
        data = self._codec.encode(change)
        if len(data) > MAX_CHANGE_BYTES:
            return f"the value is too long to send ({len(data)} bytes, at most {MAX_CHANGE_BYTES})"
        self._publishers[process].put(data)
        return ""

    def close(self) -> None:
        for publisher in self._publishers.values():
            publisher.undeclare()
        self._session.close()


class ParamListener:
    """A process's side: its key's changes handed to its scheduler's tuner."""

    def __init__(
        self,
        session: zenoh.Session,
        plan: GraphPlan,
        process: str,
        tuner: Tuner,
        log: logging.Logger | None = None,
    ) -> None:
        self._tuner = tuner
        self._log = log or logging.getLogger("umbra")
        self._codec = Codec()
        self._sub = session.declare_subscriber(param_key(plan.key_prefix, process), self._on)

    def _on(self, sample: zenoh.Sample) -> None:
        data = sample.payload.to_bytes()
        try:
            if len(data) > MAX_CHANGE_BYTES:
                raise ValueError(f"{len(data)} bytes, at most {MAX_CHANGE_BYTES}")
            change = self._codec.decode(data, ParamChange)  # raises for any other type
            value = json.loads(change.value)
        except Exception as exc:  # whatever arrives, the process goes on: say it
            self._log.warning("parameter change refused: %s", exc)
            return
        # the tuner refuses (and says) a module that does not run in this process
        self._tuner.request(change.module, change.param, value, change.by)

    def close(self) -> None:
        self._sub.undeclare()
