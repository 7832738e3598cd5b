"""Where the live server's samples come from.

- :func:`serve_local`: the outputs of the modules of this process (every output, those that feed
  nothing too), each with one more port sink, as the recorder taps them;
- :class:`ObservedFeed`: the outputs of the run's other processes, by subscribing on zenoh to
  each of their output keys as the run's observer (``umbra.runtime.links.observe``); the
  processes publish every output for observers when run with ``--publish-all`` (which
  ``--foxglove`` turns on). The run is the one its ID names (the launcher's, given to every process
  it starts): the feed waits for the run files of that run's processes, never takes another run
  of the same graph, and stops serving (saying so) once that run's processes are gone. A sample's
  log time is its arrival on this host's monotonic clock (the clock real-time runs stamp with).
"""

from __future__ import annotations

import logging
import threading
import time
from typing import TYPE_CHECKING

from umbra.runtime.live.server import LiveServer
from umbra.runtime.recording.tap import topic_of

if TYPE_CHECKING:
    from collections.abc import Callable

    from umbra.runtime.graph.plan import GraphPlan
    from umbra.runtime.links.observe import Observation, Observed, Run
    from umbra.runtime.scheduler import Scheduler

#: Seconds to keep trying to join the run as an observer (its processes start meanwhile).
JOIN_PATIENCE = 20.0


def declare_all(live: LiveServer, plan: GraphPlan) -> dict[tuple[str, str], str]:
    """A live channel for every output of every module of ``plan``; ``(module, port)`` →
    topic."""
    topics = {}
    for module, mplan in plan.modules.items():
        for port, info in mplan.outputs.items():
            topic = topic_of(module, port)
            live.declare(topic, info.msg_type)
            topics[(module, port)] = topic
    return topics


def serve_local(live: LiveServer, scheduler: Scheduler) -> list[str]:
    """One more sink on every output of this process's modules; returns the topics served."""
    topics = declare_all(live, scheduler.plan)
    served = []
    for module, instance in scheduler.modules.items():
        for port, out in instance.outputs.items():
            topic = topics.get((module, port))
            if topic is not None:
                out.sinks.append(live.sink(topic))
                served.append(topic)
    return served


class ObservedFeed:
    """The run's other processes' outputs, seen as an observer (see the module docstring)."""

    def __init__(
        self,
        live: LiveServer,
        plan: GraphPlan,
        skip: set[str] | None = None,
        log: logging.Logger | None = None,
        on_joined: Callable[[Run], None] | None = None,
        *,
        run_id: str,
    ) -> None:
        self._live = live
        self._run_id = run_id  #: the run served (``umbra.runtime.links.runs``)
        self._plan = plan
        self._topics = declare_all(live, plan)
        self._skip = set(skip or ())  #: modules whose outputs are served locally
        #: called with the run once samples of the other processes arrive
        self._on_joined = on_joined
        self._run: Run | None = None
        self._log = log or logging.getLogger("umbra.foxglove")
        self._prefix = plan.key_prefix
        self._observation: Observation | None = None
        self._stop = threading.Event()
        self.samples = 0
        self.error = ""
        self._thread = threading.Thread(target=self._join, name="umbra-fox-observe", daemon=True)
        self._thread.start()

    def _join(self) -> None:
        from umbra.connectors.errors import UserError
        from umbra.runtime.links.observe import Observation, find_run

        # a peer hears only the processes it connects to: wait for every process's run file
        expected = len(self._plan.populated_processes)
        deadline = time.monotonic() + JOIN_PATIENCE
        while not self._stop.is_set():
            run = find_run(self._run_id, self._prefix)
            try:
                if run is None or len(run.processes) < expected:
                    up = len(run.processes) if run is not None else 0
                    raise UserError(
                        f"expected the run files of the {expected} processes of run "
                        f"`{self._run_id}`, found {up}"
                    )
                observation = Observation.join(run)
            except UserError as exc:
                if time.monotonic() > deadline:
                    self.error = str(exc)
                    self._log.warning("foxglove: cannot observe the run: %s", exc)
                    return
                self._stop.wait(0.25)
                continue
            if self._stop.is_set():
                observation.close()
                return
            self._observation = observation
            self._run = run
            self._log.info("foxglove: observing run %s", run.describe())
            observation.when_ended(self._ended)
            observation.subscribe(self._on_sample, f"{self._prefix}/*/*")
            return

    def _ended(self) -> None:
        if not self._stop.is_set():
            self._log.info("foxglove: run %s ended: no more samples of its processes", self._run_id)

    def _on_sample(self, seen: Observed) -> None:
        if seen.kind != "sample" or seen.message is None:
            return
        if self._on_joined is not None:  # the first sample: the run flows
            self._first_sample()
        module, _, port = seen.key[len(self._prefix) + 1 :].partition("/")
        topic = self._topics.get((module, port))
        if topic is None or module in self._skip:
            return
        self.samples += 1
        self._live.offer(topic, seen.message, seen.arrival)

    def _first_sample(self) -> None:
        """Call ``on_joined`` once, on a thread of its own (it opens a session: never on
        zenoh's callback thread)."""
        joined, self._on_joined = self._on_joined, None
        if joined is not None and self._run is not None:
            run = self._run
            threading.Thread(target=joined, args=(run,), name="umbra-fox-join", daemon=True).start()

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)
        if self._observation is not None:
            self._observation.close()
