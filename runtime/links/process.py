"""One process of a split graph: its zenoh session and links, its scheduler, its control channel.

Started by the launcher (``supervised``: commands arrive one per line on stdin) or by hand with
``umbra run GRAPH --process NAME`` (on another host, say). The order is always:

1. open the zenoh session and build the modules; subscriptions and publishers are declared;
2. declare this process's liveliness token (consumers now know it is up);
3. wait until the consumers of every output of this process are up and subscribed, so that no
   sample is lost at start (under the launcher for at most ``ready_timeout``; by hand, forever,
   saying what it waits for every few seconds);
4. run the scheduler until the run ends; the safety guards zero their outputs first;
5. end every output stream, withdraw the token, close the session; write ``summary-NAME.json``.

Control commands (supervised, ``umbra.runtime.links.control_line``): ``finish`` — another process
ended normally: keep running until every input stream from upstream and from the process that
ended has ended (or its producer is gone) and every received sample has been handled, then stop
with status 0 (``umbra.runtime.links.finish_order``: streams of the other processes that this one
also feeds are not waited for); ``abort`` — the run failed elsewhere or was interrupted: stop
now. End of input (the launcher is gone) aborts too.
"""

from __future__ import annotations

import logging
import os
import signal
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

import zenoh

from umbra.connectors.errors import UserError
from umbra.runtime.graph.plan import GraphPlan
from umbra.runtime.links.auth import load_auth
from umbra.runtime.links.bounds import inbound_limit
from umbra.runtime.links.config import Endpoints, build_config, describe
from umbra.runtime.links.config_facts import ConfigFacts, config_facts
from umbra.runtime.links.control_line import FINISH_GRACE, ControlCommand, parse_control_line
from umbra.runtime.links.end_ack import END_ACK_ABORTED_S, END_ACK_S
from umbra.runtime.links.finish_order import mutual_peers
from umbra.runtime.links.publish_all import AllOutputs
from umbra.runtime.links.runs import BY_HAND, RunFile, describe_outputs, write_run_file
from umbra.runtime.links.session import open_session
from umbra.runtime.links.transport import ZenohTransport
from umbra.runtime.live.param_link import ParamListener
from umbra.runtime.run import write_summary
from umbra.runtime.scheduler import INTERRUPTED, Scheduler, SchedulerOptions
from umbra.runtime.stats import RunResult

#: Exit status of a process stopped because the run failed elsewhere.
ABORTED = 1
#: Zenoh's limit on the size of one received message (reassembled from fragments) [bytes].
RX_LIMIT = "transport/link/rx/max_message_size"


@dataclass
class ProcessOptions:
    """How to run one process of a split graph."""

    process: str
    output_dir: Path
    endpoints: Endpoints
    clock: str = "real"
    duration: float | None = None
    zenoh_config: str | None = None
    #: ``zenoh_config`` as the launcher already parsed it (None: parsed here)
    zenoh_facts: ConfigFacts | None = None
    #: the launcher's per-run credentials file of this process (``umbra.runtime.links.auth``)
    link_auth: str | None = None
    #: credentials of a process started by hand (``umbra.runtime.links.host_auth``), when no file
    auth: dict[str, Any] | None = None
    #: identity checks and size bounds on received samples (off only to measure their cost)
    link_checks: bool = True
    ready_timeout: float | None = None  # None: wait for consumers forever
    quiet: bool = False
    #: the CPU wake-up latency [µs] held while running (``umbra.runtime.realtime``); None: none
    cpu_latency_us: int | None = None
    #: publish every output of this process's modules for observers
    #: (``umbra.runtime.links.publish_all``)
    publish_all: bool = False
    #: write a run file for observers of this user (``umbra.runtime.links.runs``); off in tests that
    #: share no user folder
    run_file: bool = True
    #: a person runs this run (``SchedulerOptions.attended``)
    attended: bool = False
    #: the run this process belongs to, written in its run file (``umbra.runtime.links.runs``)
    run_id: str = BY_HAND
    #: when the launcher started the run [s since the epoch] (0: started by hand)
    run_started: float = 0.0
    #: ``--ros2``: this process's ROS 2 node (``SchedulerOptions.ros2``); None: none
    ros2: Any = None
    extra: dict[str, Any] = field(default_factory=dict)


class _Control:
    """Reads launcher commands from ``stream`` on its own thread and acts on the scheduler."""

    def __init__(
        self,
        stream: TextIO,
        scheduler: Scheduler,
        transport: ZenohTransport,
        stop: threading.Event,
        log: logging.Logger,
        peers: frozenset[str] = frozenset(),
    ) -> None:
        self._stream, self._scheduler, self._transport = stream, scheduler, transport
        self._stop, self._log = stop, log
        #: processes that feed this one and are fed by it: finishing, it does not wait for them
        self._peers = peers
        self._thread = threading.Thread(target=self._read, name="umbra-control", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def _read(self) -> None:
        for line in self._stream:
            if not line.strip():
                continue
            told = parse_control_line(line)
            if isinstance(told, str):
                self._log.warning("%s: ignored", told)
            elif told.command is ControlCommand.FINISH:
                self._finish(told.reason or "another process finished", told.finished)
            else:
                self._abort(told.reason or "stopped by the launcher")
        self._abort("the launcher is gone (its control pipe closed)")

    def _abort(self, reason: str) -> None:
        self._scheduler.request_stop(reason, ABORTED)
        self._stop.set()

    def _finish(self, reason: str, finished: str | None) -> None:
        # the streams of the process that ended are waited for even when it is a mutual peer:
        # it ended, so they end (a verdict it sent just before reaches this process's modules)
        closed = frozenset({finished} if finished else ())
        besides = self._peers - closed
        deadline = time.monotonic() + FINISH_GRACE
        while time.monotonic() < deadline and not self._stop.is_set():
            ended = self._transport.inputs_ended(besides=besides, closed=closed)
            if ended and self._scheduler.pending_link_samples == 0:
                break
            time.sleep(0.005)
        else:
            if not self._stop.is_set():
                self._log.warning("input streams still open %.0f s after: %s", FINISH_GRACE, reason)
        self._scheduler.request_stop(f"finished: {reason}", 0)
        self._stop.set()


def _interruptible(stop: threading.Event, scheduler: Scheduler) -> dict[int, Any]:
    """SIGINT/SIGTERM from before the links start until the summary is written (the scheduler
    routes them to itself while it runs): stop cleanly (exit 130), never a KeyboardInterrupt."""
    if threading.current_thread() is not threading.main_thread():
        return {}

    def on_signal(signum: int, frame: Any) -> None:
        scheduler.request_stop(f"interrupted by {signal.Signals(signum).name}", INTERRUPTED)
        stop.set()

    return {sig: signal.signal(sig, on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}


def _run_file(
    plan: GraphPlan,
    options: ProcessOptions,
    auth: dict[str, Any] | None,
    own_rules: bool,
    supervised: bool,
) -> Path | None:
    """Write this process's run file for observers of this user (None when the user's folder
    cannot take one: observing is then unavailable, the run goes on)."""
    if own_rules or (auth is None and options.zenoh_config):
        access = "config"
    elif auth is None:
        access = "insecure"
    else:
        access = "credentials"
    entry = RunFile(
        graph=plan.spec.name,
        prefix=plan.key_prefix,
        process=options.process,
        pid=os.getpid(),
        listen=list(options.endpoints.listen),
        access=access,
        publish_all=options.publish_all,
        outputs=describe_outputs(plan, options.process),
        observer=auth.get("observer") if auth else None,  # TLS under the launcher: both
        started=time.time(),
        run_id=options.run_id,
        launcher=os.getppid() if supervised else 0,
        run_started=options.run_started,
        run_processes=len(plan.populated_processes),
    )
    try:
        return write_run_file(entry)
    except (OSError, UserError) as exc:
        logging.getLogger("umbra").warning("no run file for observers: %s", exc)
        return None


def run_linked_process(
    plan: GraphPlan,
    options: ProcessOptions,
    control: TextIO | None = None,
    log: logging.Logger | None = None,
) -> RunResult:
    """Run process ``options.process`` of ``plan`` with zenoh links; always writes
    ``summary-<process>.json``. UserError for a bad configuration (nothing started then)."""
    log = log or logging.getLogger("umbra")
    options.output_dir.mkdir(parents=True, exist_ok=True)
    auth = load_auth(options.link_auth) if options.link_auth else options.auth
    facts = options.zenoh_facts or config_facts(options.zenoh_config)
    if auth is not None and facts.access_control:
        auth.pop("access_control", None)  # the file's rules (``umbra keys``: by certificate)
    config = build_config(options.endpoints, options.zenoh_config, auth, facts.config)
    if options.link_checks and config.get_json(RX_LIMIT) == zenoh.Config().get_json(RX_LIMIT):
        config.insert_json5(RX_LIMIT, str(inbound_limit(plan, options.process)))
    session = open_session(config)
    log.info("process `%s`: %s", options.process, describe(config))
    transport = ZenohTransport(
        session,
        plan,
        options.process,
        log=log.getChild("links"),
        checks=options.link_checks,
        token_key=auth.get("token_key") if auth else None,
    )
    try:
        scheduler = Scheduler(
            plan,
            SchedulerOptions(
                clock=options.clock,
                duration=options.duration,
                output_dir=options.output_dir,
                process=options.process,
                handle_signals=True,
                log=log,
                dispatch=plan.spec.links.dispatch,
                cpu_latency_us=options.cpu_latency_us,
                attended=options.attended,
                ros2=options.ros2,
            ),
            transport,
        )
    except BaseException:
        transport.close()
        raise
    everything = (
        AllOutputs(
            session,
            plan,
            options.process,
            scheduler.modules,
            {link.key for link in plan.links},
            log.getChild("links"),
        )
        if options.publish_all
        else None
    )
    # a run served live: the live server's parameter changes for this process's modules
    tuning = (
        ParamListener(session, plan, options.process, scheduler.tuner, log)
        if auth is not None and auth.get("tuner")
        else None
    )
    supervised = control is not None
    run_file = (
        _run_file(plan, options, auth, facts.access_control, supervised)
        if options.run_file
        else None
    )
    stop = threading.Event()
    result: RunResult | None = None
    # From here until the summary is written, Ctrl-C and SIGTERM request a stop (the scheduler
    # routes them to itself while it runs): never a KeyboardInterrupt that skips the summary.
    old = _interruptible(stop, scheduler)
    try:
        try:
            transport.announce()
            if control is not None:
                peers = mutual_peers(plan, options.process)
                _Control(control, scheduler, transport, stop, log, peers).start()
            try:
                ready = transport.wait_ready(stop, options.ready_timeout)
            except TimeoutError as exc:
                scheduler.request_stop(
                    f"consumers did not come within {options.ready_timeout:g} s: {exc}", 1
                )
                ready = False
            if ready:
                log.info("process `%s`: links ready, running", options.process)
            result = scheduler.run()
        finally:
            if tuning is not None:
                tuning.close()
            if everything is not None:
                everything.close()
            ended_normally = result is not None and result.exit_code == 0
            transport.close(END_ACK_S if ended_normally else END_ACK_ABORTED_S)
            if run_file is not None:
                run_file.unlink(missing_ok=True)
        result.extra.update(options.extra)
        write_summary(result, options.output_dir, options.process)
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)
    return result
