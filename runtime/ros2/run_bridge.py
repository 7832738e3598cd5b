"""The ROS 2 side of one process of a run (``umbra run GRAPH --ros2``): a :class:`Ros2Bridge`
beside the process's links, for the ports of the graph's ``ros2:`` section that this process owns
(``GraphPlan.ros2``: a mapping belongs to its module's process).

- An output mapped ``out`` gets one more sink, as a recording's tap does
  (``umbra.runtime.recording.tap``): the sample is handed to a publishing thread that keeps the
  newest per topic (state, latest-only, as a link's publisher drops under congestion) and sends
  it as CDR, so converting a 1280x720 frame never lengthens a tick. When the loop ends the thread
  sends what is left — the safe-stop zeros a guard sends last reach the ROS 2 arm — and the node
  closes.
- An input mapped ``in`` is written into its register as a link sample is
  (``umbra.runtime.link_inbox``): queued for the next tick, dated by the message's
  ``header.stamp`` (its ``origin`` moved into the past by the mapping's error bound), the
  newest winning; a tick runs at once when the loop is idle (``dispatch: inline``). One topic may
  feed several inputs of the process.

The ROS 2 node's zenoh session is its own, a client of the ROS 2 router: the run's links stay on
their session, which no ROS 2 peer reaches. The summary says, per topic, what was sent, received,
refused and dropped, and the origin ages of the inputs' samples as they arrived [s].
"""

from __future__ import annotations

import logging
import math
import threading
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import msgspec
import numpy as np

from umbra.connectors.errors import UserError
from umbra.connectors.messages import Message, Pose
from umbra.connectors.module import Module
from umbra.connectors.ports import Register
from umbra.runtime.graph.plan import GraphPlan
from umbra.runtime.graph.spec_ros2 import DEFAULT_ROS2_ROUTER as DEFAULT_ROUTER
from umbra.runtime.links.exposure import config_for
from umbra.runtime.ros2.bridge import MAX_DOMAIN, Ros2Bridge
from umbra.runtime.ros2.mapping import Direction, Ros2Mapping
from umbra.runtime.ros2.router import session_config

#: ROS 2's transform topics and their type: a process that maps an output to ``/tf`` also
#: publishes the graph's static frames on ``/tf_static``, every ``STATIC_PERIOD_S`` [s].
TF, TF_STATIC, TF_TYPE = "/tf", "/tf_static", "tf2_msgs/msg/TFMessage"
STATIC_PERIOD_S = 1.0
#: Origin ages kept per input topic for the summary (the newest ones).
AGES_KEPT = 20_000


@dataclass(frozen=True)
class Ros2RunOptions:
    """``--ros2``: the ROS 2 ``domain``, the ``router`` endpoint our node connects to, and a zenoh
    configuration file (TLS with the graph's certificates) for that session."""

    domain: int = 0
    router: str = DEFAULT_ROUTER
    config_file: str | None = None

    def __post_init__(self) -> None:
        if isinstance(self.domain, bool) or not 0 <= self.domain <= MAX_DOMAIN:
            raise UserError(
                f"--ros2-domain: expected a ROS 2 domain id 0..{MAX_DOMAIN}, found {self.domain}"
            )

    def config_of(self, process: str | None) -> str | None:
        """The ROS 2 session's configuration file for ``process`` (the links' rule,
        ``umbra.runtime.links.exposure.config_for``: a folder holds ``PROCESS.json5``);
        UserError for a folder in a run of one process, which names none."""
        path = self.config_file
        if path is None:
            return None
        if process is None and Path(path).is_dir():
            raise UserError(
                "--ros2-config: expected a zenoh configuration file for a run of one process, "
                f"found the folder {path} (give one of its PROCESS.json5)"
            )
        return config_for(path, process) if process is not None else path


def node_name(plan: GraphPlan, process: str | None) -> str:
    """The ROS 2 node of ``process``: the section's ``node``, ``<node>_<process>`` in a split
    run (each process is a node of its own)."""
    base = plan.spec.ros2.node
    return base if process is None else f"{base}_{process}"


@dataclass
class _Outgoing:
    """Samples waiting to be published: the newest per topic, and how many were replaced."""

    latest: dict[str, Message] = field(default_factory=dict)
    dropped: dict[str, int] = field(default_factory=dict)
    closing: bool = False
    cond: threading.Condition = field(default_factory=threading.Condition)


class RunBridge:
    """The ROS 2 node of one process of a run (see the module docstring)."""

    def __init__(
        self,
        plan: GraphPlan,
        process: str | None,
        modules: Mapping[str, Module[Any]],
        deliverer: Callable[[Register[Any]], Callable[[Message], None]],
        arrived: Callable[[], None],
        clock: Callable[[], float],
        options: Ros2RunOptions,
        log: logging.Logger | None = None,
    ) -> None:
        self._log = log or logging.getLogger("umbra.ros2")
        self._clock = clock
        ports = [p for p in plan.ros2 if process is None or p.process == process]
        by_topic: dict[str, list[Any]] = {}
        for p in ports:
            by_topic.setdefault(p.mapping.topic, []).append(p)
        self.ports = ports
        self.options = options
        mappings = [group[0].mapping for group in by_topic.values()]
        #: the graph's static frames, on /tf_static beside the process's /tf (ROS 2's rule)
        self._static = static_frames(plan) if TF in by_topic else []
        if self._static:
            mappings.append(Ros2Mapping(TF_STATIC, TF_TYPE, "Pose", Direction.OUT))
        self.bridge = Ros2Bridge(
            session_config(options.router, config_file=options.config_of(process)),
            options.domain,
            node_name(plan, process),
            mappings,
            run_clock=clock,
            log=self._log,
        )
        self.ages: dict[str, deque[float]] = {}
        self._arrived = arrived
        self._out = _Outgoing()
        self._thread: threading.Thread | None = None
        for topic, group in by_topic.items():
            if group[0].mapping.direction.value == "out":
                p = group[0]
                self._out.dropped[topic] = 0
                output = modules[p.module].outputs[p.port]
                output.sinks.append(self._sink(topic))
                output.connected = True  # a ROS 2 subscriber listens: the module may send
            else:
                regs = []
                for p in group:
                    reg = modules[p.module].registers[p.port]
                    reg.connected, reg.events = True, False
                    regs.append(reg)
                self.ages[topic] = deque(maxlen=AGES_KEPT)
                self.bridge.subscribe(topic, self._taker(topic, [deliverer(r) for r in regs]))
        if self._out.dropped:
            self._thread = threading.Thread(target=self._publish, name="umbra-ros2", daemon=True)
            self._thread.start()
        self._static_sent_at = -math.inf

    # -- out -------------------------------------------------------------------------------------
    def _sink(self, topic: str) -> Callable[[Message, float], None]:
        out = self._out

        def sink(sample: Message, now: float) -> None:
            with out.cond:
                if topic in out.latest:
                    out.dropped[topic] += 1
                out.latest[topic] = sample
                out.cond.notify()

        return sink

    def _publish(self) -> None:
        out = self._out
        while True:
            with out.cond:
                while not out.latest and not out.closing:
                    out.cond.wait()
                if not out.latest:
                    return
                batch, out.latest = out.latest, {}
            self._send_static()
            for topic, sample in batch.items():
                try:
                    self.bridge.publish(topic, sample)
                except Exception as exc:  # a sample that does not convert: said, counted
                    stats = self.bridge.stats[topic]
                    stats.refused += 1
                    stats.last_refusal = f"{type(exc).__name__}: {exc}"
                    self._log.warning("ROS 2 output %s not sent: %s", topic, exc)

    def _send_static(self) -> None:
        """The static frames on ``/tf_static``, at start and every ``STATIC_PERIOD_S`` [s] (no
        transient-local cache here: a subscriber that comes later gets them within a period)."""
        now = self._clock()
        if not self._static or now - self._static_sent_at < STATIC_PERIOD_S:
            return
        self._static_sent_at = now
        for frame in self._static:
            self.bridge.publish(TF_STATIC, msgspec.structs.replace(frame, stamp=now, origin=now))

    # -- in --------------------------------------------------------------------------------------
    def _taker(
        self, topic: str, deliver: list[Callable[[Message], None]]
    ) -> Callable[[Message], None]:
        ages = self.ages[topic]
        clock, arrived = self._clock, self._arrived

        def take(sample: Message) -> None:
            ages.append(clock() - sample.origin)
            for d in deliver:
                d(sample)
            arrived()

        return take

    # -- end -------------------------------------------------------------------------------------
    def close(self) -> None:
        """Send what waits, then undeclare the node and close its session."""
        with self._out.cond:
            self._out.closing = True
            self._out.cond.notify()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        self.bridge.close()

    def summary(self) -> dict[str, Any]:
        """Per topic: port, direction, type and counts; for inputs the origin ages [s] of the
        samples as they arrived (median, p95, max; ``undated``: samples whose stamp could not be
        related)."""
        topics: dict[str, Any] = {}
        for p in self.ports:
            m = p.mapping
            entry = topics.setdefault(
                m.topic,
                {
                    "ports": [],
                    "direction": m.direction.value,
                    "type": m.ros_type,
                    **self.bridge.stats[m.topic].as_dict(),
                },
            )
            entry["ports"].append(str(p))
            if m.topic in self._out.dropped:
                entry["dropped"] = self._out.dropped[m.topic]
            if m.topic in self.ages:
                entry["origin_age_s"] = age_figures(list(self.ages[m.topic]))
        return {
            "domain": self.options.domain,
            "router": self.options.router,
            "node": self.bridge.node.name,
            "topics": topics,
        }


def static_frames(plan: GraphPlan) -> list[Pose]:
    """The graph's static frames (``frames:``), one ``Pose`` each (``T_parent_child``)."""
    return [
        Pose(matrix=np.asarray(f.T_parent_child, dtype=float), parent=f.parent, child=f.child)
        for f in plan.spec.frames
    ]


def age_figures(ages: list[float]) -> dict[str, Any]:
    """Median, p95 and max [s] of the finite ``ages``, and how many were not (undated)."""
    finite = np.asarray([a for a in ages if math.isfinite(a)], dtype=np.float64)
    figures: dict[str, Any] = {"samples": len(ages), "undated": len(ages) - finite.size}
    if finite.size:
        figures.update(
            median=float(np.median(finite)),
            p95=float(np.percentile(finite, 95)),
            max=float(finite.max()),
        )
    return figures


def ros2_lines(summary: dict[str, Any] | None) -> list[str]:
    """The run summary's lines for the ROS 2 side (none without one)."""
    if not summary:
        return []
    lines = [f"ros2: node {summary['node']} on domain {summary['domain']} via {summary['router']}"]
    for topic, t in summary["topics"].items():
        counts = (
            f"sent {t['sent']}, dropped {t.get('dropped', 0)}"
            if t["direction"] == "out"
            else f"received {t['received']}"
        )
        refused = f", refused {t['refused']} ({t['last_refusal']})" if t["refused"] else ""
        line = f"  {t['direction']:3} {topic} ({t['type']}) {', '.join(t['ports'])}: {counts}"
        ages = t.get("origin_age_s")
        if ages and "median" in ages:
            line += (
                f"; origin age median {ages['median'] * 1e3:.1f} ms, p95 "
                f"{ages['p95'] * 1e3:.1f} ms, max {ages['max'] * 1e3:.1f} ms"
            )
        if ages and ages["undated"]:
            line += f", {ages['undated']} undated"
        lines.append(line + refused)
    return lines


def attach_ros2(scheduler: Any, options: Ros2RunOptions) -> RunBridge | None:
    """The ROS 2 node of the scheduler's process (None when it owns no mapping); UserError on
    the sim clock (ROS 2 stamps are wall-clock time, which sim time is not)."""
    plan: GraphPlan = scheduler.plan
    process = scheduler.options.process
    if not any(process is None or p.process == process for p in plan.ros2):
        return None
    if scheduler.clock.kind != "real":
        raise UserError(
            "--ros2: ROS 2 stamps are wall-clock time: expected the real clock, found the sim "
            "clock; add --clock real"
        )
    return RunBridge(
        plan,
        process,
        scheduler.modules,
        lambda reg: scheduler._deliverer(reg, False),
        scheduler._arrived,
        scheduler.clock.now,
        options,
        scheduler.options.log,
    )
