"""``umbra run GRAPH --foxglove``: the live server, its gate and its feeds for one run."""

from __future__ import annotations

import logging
import secrets
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from umbra.connectors.access.hosts import origin_problem, port_problem
from umbra.connectors.access.secret import is_loopback, resolve_token
from umbra.connectors.errors import UserError
from umbra.runtime.links.acl import TUNER_USER
from umbra.runtime.links.observe import local_config
from umbra.runtime.links.session import open_session, wait_joined
from umbra.runtime.live.feed import ObservedFeed, serve_local
from umbra.runtime.live.gate import DEFAULT_ORIGINS
from umbra.runtime.live.param_link import ParamSender
from umbra.runtime.live.parameters import ParameterTable
from umbra.runtime.live.server import LiveServer
from umbra.runtime.live.viewer_server import ViewerServer
from umbra.runtime.recording.foxglove_msgs import wall_offset

if TYPE_CHECKING:
    from umbra.runtime.graph.plan import GraphPlan
    from umbra.runtime.links.observe import Run
    from umbra.runtime.scheduler import Scheduler

#: Seconds the tuner's session has to reach every process of the run.
TUNER_PATIENCE = 5.0
#: Foxglove's conventional port for its WebSocket protocol.
DEFAULT_PORT = 8765


@dataclass
class LiveOptions:
    """Where and to whom the run is served live."""

    host: str = "127.0.0.1"
    port: int = DEFAULT_PORT
    origins: list[str] = field(default_factory=list)  #: viewer pages allowed beyond the default
    token_file: str = ""  #: first line: the access token (else the pages' file, else random)
    images: str = "jpeg"  #: how images are served: jpeg, png or raw
    insecure: bool = False  #: allow a host beyond loopback (plain ws://, no TLS)


def page_token_file(plan: GraphPlan) -> str:
    """The ``token_file`` of the graph's operator pages (the console's, the sketch page's), so the
    live server takes the same secret as the pages; empty when they make a random one."""
    for mplan in plan.modules.values():
        value = getattr(mplan.params, "token_file", "")
        if isinstance(value, str) and value:
            return value
    return ""


class LiveRun:
    """The live server of one run: :meth:`serve` this process's outputs, :meth:`observe` the
    others'; :attr:`url` is what a viewer opens."""

    def __init__(
        self, plan: GraphPlan, options: LiveOptions, clock: Any, log: logging.Logger | None = None
    ) -> None:
        if problem := port_problem(options.port):
            raise UserError(f"--foxglove-port: {problem}")
        for origin in options.origins:
            if problem := origin_problem(origin):
                raise UserError(f"--foxglove-origin: {problem}")
        if not is_loopback(options.host) and not options.insecure:
            raise UserError(
                f"--foxglove-host: expected a loopback address (the live server speaks plain "
                f"ws://, without TLS), found {options.host}; add --insecure to serve beyond it"
            )
        self.plan = plan
        self.log = log or logging.getLogger("umbra.foxglove")
        token = resolve_token(options.token_file or page_token_file(plan), "--foxglove")
        self.parameters = ParameterTable(plan, self.log)
        try:
            self.gate = ViewerServer(
                name=f"umbra {plan.spec.name}",
                host=options.host,
                port=options.port,
                token=token,
                origins=[*DEFAULT_ORIGINS, *options.origins],
                parameters=self.parameters,
                log=self.log,
            )
        except OSError as exc:
            raise UserError(
                f"--foxglove-port: cannot listen on {options.host}:{options.port}: "
                f"{exc.strerror or exc} (give another port, or 0 for any free one)"
            ) from None
        self.server = LiveServer(
            socket=self.gate,
            clock_offset=wall_offset(clock.now()),
            images=options.images,
            log=self.log,
        )
        frames = [(f.parent, f.child, f.T_parent_child) for f in plan.spec.frames]
        self.server.set_static_frames(frames, clock)
        self._feed: ObservedFeed | None = None
        self._sender: ParamSender | None = None
        self._local_modules: set[str] = set()
        self.local: list[str] = []
        #: the password the launcher gives the run's tuner (``umbra.runtime.links.auth``): only this
        #: process may send parameter changes to the others
        self.tuner_password = secrets.token_hex(24)

    @property
    def url(self) -> str:
        return self.gate.url

    def serve(self, scheduler: Scheduler) -> None:
        """Serve every output of the modules of ``scheduler`` (this process); changes of their
        tunable parameters go to its tuner."""
        self.local = serve_local(self.server, scheduler)
        self._local_modules = set(scheduler.modules)
        self.parameters.serve_locally(scheduler.tuner, list(scheduler.modules))

    def observe(self, run_id: str, skip: set[str] | None = None) -> None:
        """Serve the outputs of the other processes of run ``run_id`` (this run's ID, which the
        launcher gives its processes), observed on zenoh (``--publish-all``); changes of their
        tunable parameters go to them over the run's parameter link once they are up."""
        self._feed = ObservedFeed(
            self.server, self.plan, skip, self.log, self._join_as_tuner, run_id=run_id
        )

    def _join_as_tuner(self, run: Run) -> None:
        """Open the tuner's session to ``run``'s processes (a local run the launcher secures
        with its credentials; else the other processes take no changes)."""
        if run.access != "credentials":
            self.log.info(
                "foxglove: parameters of other processes cannot be changed (%s)", run.access
            )
            return
        try:
            cfg = local_config(
                run, credentials={"user": TUNER_USER, "password": self.tuner_password}
            )
            session = open_session(cfg)
        except Exception as exc:  # the run goes on, read only: say why
            self.log.warning("foxglove: cannot send parameter changes: %s", exc)
            return
        if wait_joined(session, len(run.processes), TUNER_PATIENCE) < len(run.processes):
            session.close()  # processes started by hand know no tuner
            self.log.warning(
                "foxglove: parameters of other processes cannot be changed: the credentials of "
                "run %s do not let this process send changes (its processes were not started "
                "by this launcher)",
                run.run_id,
            )
            return
        sender = ParamSender(session, self.plan)
        self._sender = sender
        remote = [m for m in self.plan.modules if m not in self._local_modules]
        self.parameters.send_remotely(sender.send, remote)
        processes = ", ".join(p.process for p in run.processes)
        self.log.info("foxglove: parameter changes reach processes %s", processes)

    def close(self) -> None:
        if self._feed is not None:
            self._feed.close()
        if self._sender is not None:
            self._sender.close()
        self.server.close()
        self.gate.close()

    def summary(self) -> dict[str, Any]:
        found = self.server.summary()
        found["viewers_refused"] = self.gate.refused
        found["viewers"] = self.gate.passed
        found["viewer_backlog_dropped"] = self.gate.dropped
        found["viewers_cut_off"] = self.gate.cut_off
        if self._feed is not None:
            found["observed"] = self._feed.samples
        return found
