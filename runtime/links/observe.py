"""Observing a running graph: a read-only zenoh session that subscribes to its outputs and decodes.

``Observation.open`` joins a graph as an observer (``umbra.runtime.links.acl.Observer``):

* on this host, with no setup: the run files of this user's processes (``umbra.runtime.links.runs``)
  give the run (its ID), the prefix, the endpoints to connect to and the run's observer
  credentials. Several runs of one graph are told apart by their run ID: ``run_id`` names one,
  else the newest is taken. An observation stays with its run: once every process of the run is
  gone, :attr:`Observation.ended` is set and nothing more is delivered (zenoh would reconnect to
  whatever listens on the same endpoints next);
* elsewhere: a zenoh configuration (``umbra keys GRAPH --observer NAME`` writes one: mutual TLS
  with an observer certificate) and the endpoints to connect to.

``subscribe(on_sample)`` calls ``on_sample(Observed)`` on zenoh's threads for every sample and end
of stream under the key expression (every output key it may read by default), decoded with
``umbra.connectors.codec``;
``producers()`` maps each live process to its session (the liveliness tokens, section 2 of
``docs/wire-format.md``). Other tools (a Foxglove bridge) use this; the ``umbra topics``,
``echo`` and ``hz`` commands too.
"""

from __future__ import annotations

import contextlib
import json
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import zenoh

from umbra.connectors.codec import Codec
from umbra.connectors.errors import UserError
from umbra.connectors.messages import Message
from umbra.runtime.links.config import Endpoints, build_config
from umbra.runtime.links.identity import alive_pattern, parse_alive_key
from umbra.runtime.links.pool import DESCRIPTOR_MAGIC, FORWARD_MAGIC, pid_alive
from umbra.runtime.links.runs import RunFile, live_runs, observer_endpoint
from umbra.runtime.links.session import open_session, wait_joined
from umbra.runtime.links.wire import POOL_MEDIA_TYPE, parse_encoding

#: Seconds to wait for the sessions of a run's processes when joining it (and for the run files
#: of a run whose processes are still starting).
JOIN_TIMEOUT = 3.0
#: Seconds between two looks at whether the observed run's processes are still alive.
WATCH_PERIOD = 0.2
#: Beside an observer's zenoh configuration ``observer@NAME.json5``: its prefix and keys.
KEYS_SUFFIX = ".keys.json"


@dataclass
class Observed:
    """One sample (or end of stream) seen by an observer."""

    key: str
    #: "sample", "end" (the producer ended the stream) or "undecodable"
    kind: str
    message: Message | None
    #: the type the encoding names ("" when it names none)
    type_name: str
    size: int  #: payload bytes
    source: str  #: zenoh id of the session that put it ("" when unstamped)
    arrival: float  #: ``time.monotonic()`` at arrival [s]
    error: str = ""


@dataclass
class Run:
    """A graph running on this host, from its processes' run files."""

    graph: str
    prefix: str
    run_id: str
    processes: list[RunFile] = field(default_factory=list)

    @property
    def access(self) -> str:
        return self.processes[0].access if self.processes else "credentials"

    @property
    def started(self) -> float:
        """When the launcher started the run, else its first process [s since the epoch]."""
        return min((p.run_started or p.started for p in self.processes), default=0.0)

    @property
    def expected(self) -> int:
        """How many processes the run has (as many as have run files when they do not say)."""
        return max([len(self.processes)] + [p.run_processes for p in self.processes])

    @property
    def complete(self) -> bool:
        """Every process of the run has written its run file."""
        return len(self.processes) >= self.expected

    def alive(self) -> bool:
        """Some process of the run is alive."""
        return any(pid_alive(p.pid) for p in self.processes)

    def describe(self) -> str:
        """``ID (graph NAME, launcher pid N, started YYYY-mm-dd HH:MM:SS, k of n processes)``."""
        launcher = self.processes[0].launcher if self.processes else 0
        pids = ", ".join(str(p.pid) for p in self.processes)
        who = f"launcher pid {launcher}" if launcher else f"started by hand, pid {pids}"
        when = time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(self.started))
        return (
            f"{self.run_id} (graph {self.graph}, {who}, started {when}, "
            f"{len(self.processes)} of {self.expected} processes)"
        )


def local_runs(folder: Path | None = None) -> list[Run]:
    """The runs of this user on this host now, by graph, prefix and run ID; oldest first."""
    runs: dict[tuple[str, str, str], Run] = {}
    for entry in live_runs(folder):
        at = (entry.graph, entry.prefix, entry.run_id)
        runs.setdefault(at, Run(*at)).processes.append(entry)
    return sorted(runs.values(), key=lambda r: r.started)


def find_run(run_id: str, graph: str | None = None, folder: Path | None = None) -> Run | None:
    """The local run ``run_id`` (of ``graph``, its name or prefix, when given); None when no
    process of it has written its run file (yet, or any more)."""
    for run in local_runs(folder):
        if run.run_id == run_id and graph in (None, run.graph, run.prefix):
            return run
    return None


def choose_run(graph: str | None, folder: Path | None = None, run_id: str | None = None) -> Run:
    """The local run to observe: ``run_id`` when given, else the newest run of ``graph`` (its
    name or prefix; of the only graph running when None). UserError saying what runs when there
    is no such run, or several graphs run and none is named."""
    runs = local_runs(folder)
    mine = [r for r in runs if graph in (None, r.graph, r.prefix)]
    if run_id is not None:
        found = [r for r in mine if r.run_id == run_id]
        if len(found) == 1:
            return found[0]
        if not found:
            of = f" of graph `{graph}`" if graph else ""
            raise UserError(
                f"--run: expected a run{of} on this host for this user, found no run "
                f"`{run_id}`; runs: {runs_text(runs)}"
            )
        mine = found  # one ID in several graphs (processes started by hand): name the graph
    if not mine:
        what = f"no run of graph `{graph}` is up" if graph else "no graph runs"
        raise UserError(
            f"error: {what} on this host for this user (no live run file in "
            f"{_runs_folder_text(folder)}); start one with `umbra run GRAPH`, or observe a "
            f"run elsewhere with --zenoh-config OBSERVER.json5 --connect ENDPOINT"
        )
    graphs = sorted({f"{r.graph} (prefix {r.prefix})" for r in mine})
    if len(graphs) > 1:
        raise UserError(
            f"error: expected one graph running on this host, found {len(graphs)}: "
            f"{'; '.join(graphs)}; name one with --graph NAME (or its prefix); runs: "
            f"{runs_text(mine)}"
        )
    return mine[-1]  # the newest


def sibling_runs(run: Run, folder: Path | None = None) -> list[Run]:
    """The other local runs of ``run``'s graph (same name and prefix), oldest first."""
    return [
        r
        for r in local_runs(folder)
        if (r.graph, r.prefix) == (run.graph, run.prefix) and r.run_id != run.run_id
    ]


def runs_text(runs: list[Run]) -> str:
    """``runs`` named for a message (``none`` when empty)."""
    return "; ".join(r.describe() for r in runs) or "none"


def _runs_folder_text(folder: Path | None) -> str:
    from umbra.runtime.links.runs import runs_folder

    return str(runs_folder(folder))


def local_config(
    run: Run, zenoh_config: str | None = None, credentials: dict[str, str] | None = None
) -> zenoh.Config:
    """The observer's configuration for a local run: its processes' endpoints, the run's
    observer password (or ``credentials``: user and password of another of the run's
    subjects), and ``zenoh_config`` (an observer certificate) for a run with TLS."""
    endpoints = sorted({observer_endpoint(e) for p in run.processes for e in p.listen})
    if run.access == "config" and not zenoh_config:
        raise UserError(
            f"error: graph `{run.graph}` runs with a zenoh configuration of its own (TLS "
            f"certificates): observe it with an observer certificate, made with the others by "
            f"`umbra keys GRAPH --out DIR --observer NAME`: --zenoh-config "
            f"DIR/observer@NAME.json5"
        )
    cfg = build_config(Endpoints(connect=endpoints), zenoh_config)
    observer = credentials or run.processes[0].observer
    if observer:  # the run's password too (the launcher's runs have one, TLS or not)
        usrpwd = {"user": observer["user"], "password": observer["password"]}
        cfg.insert_json5("transport/auth/usrpwd", json.dumps(usrpwd))
    return cfg


def observer_keys(zenoh_config: str) -> tuple[str, list[str]] | None:
    """The prefix and keys of an observer configuration written by ``umbra keys``: the file
    ``KEYS_SUFFIX`` beside it (None when there is none)."""
    path = Path(zenoh_config).with_suffix(KEYS_SUFFIX)
    try:
        data = json.loads(path.read_text())
        return str(data["prefix"]), [str(k) for k in data["keys"]]
    except (OSError, ValueError, KeyError, TypeError):
        return None


class Observation:
    """A read-only session on a graph's keys (see the module docstring)."""

    def __init__(
        self,
        session: zenoh.Session,
        prefix: str,
        run: Run | None = None,
        keys: list[str] | None = None,
    ) -> None:
        self.session = session
        self.prefix = prefix
        self.run = run
        #: the output keys this observer may read, when known (zenoh's access rules refuse a
        #: subscription to a key expression wider than the keys an observer is allowed)
        self.keys = keys
        if keys is None and run is not None:
            self.keys = sorted(
                o.key for p in run.processes for o in p.outputs if o.link or p.publish_all
            )
        self._subs: list[Any] = []
        self._local = threading.local()
        #: set once every process of the observed local run is gone: from then on nothing more
        #: is delivered (the session may reach another run on the same endpoints: never)
        self.ended = threading.Event()
        self._on_end: Callable[[], None] | None = None
        self._end_lock = threading.Lock()
        self._closed = threading.Event()
        if run is not None:
            threading.Thread(target=self._watch, name="umbra-observe-run", daemon=True).start()

    @classmethod
    def open(
        cls,
        graph: str | None = None,
        *,
        prefix: str | None = None,
        zenoh_config: str | None = None,
        connect: list[str] | None = None,
        folder: Path | None = None,
        run_id: str | None = None,
    ) -> Observation:
        """Join a graph: a local run of this user (``run_id`` names it, else the newest run of
        ``graph``, which names the graph when several run), or, with ``zenoh_config`` and
        ``connect``, a run elsewhere (``prefix``, else ``umbra/<graph>``). UserError when there
        is none or it cannot be joined."""
        if zenoh_config and not connect:  # a local run with TLS: its endpoints, a certificate
            run = choose_run(graph, folder, run_id)
            return cls.join(run, zenoh_config, folder)
        if zenoh_config or connect:
            readable = observer_keys(zenoh_config) if zenoh_config else None
            if readable is not None:
                prefix = prefix or readable[0]
            if not (prefix or graph):
                raise UserError("error: with --connect, name the graph (--graph) or --prefix")
            cfg = build_config(Endpoints(connect=list(connect or [])), zenoh_config)
            session = open_session(cfg)
            keys = readable[1] if readable is not None else None
            observation = cls(session, prefix or f"umbra/{graph}", keys=keys)
            observation._wait_joined(1)
            return observation
        return cls.join(choose_run(graph, folder, run_id), folder=folder)

    @classmethod
    def join(
        cls, run: Run, zenoh_config: str | None = None, folder: Path | None = None
    ) -> Observation:
        """Join the local ``run`` (with ``zenoh_config``, an observer certificate, for a run with
        TLS), once its processes that are still starting have written their run files (at most
        ``JOIN_TIMEOUT`` s). UserError when it cannot be joined."""
        deadline = time.monotonic() + JOIN_TIMEOUT
        while not run.complete and time.monotonic() < deadline:
            time.sleep(WATCH_PERIOD)
            run = find_run(run.run_id, run.prefix, folder) or run
        readable = observer_keys(zenoh_config) if zenoh_config else None
        session = open_session(local_config(run, zenoh_config))
        keys = readable[1] if readable is not None else None
        observation = cls(session, run.prefix, run, keys=keys)
        observation._wait_joined(len(run.processes))
        return observation

    def when_ended(self, callback: Callable[[], None]) -> None:
        """Call ``callback`` once the observed run has ended (on the observation's thread, or
        now when it has ended already)."""
        with self._end_lock:
            self._on_end = callback
            now = self.ended.is_set()
        if now:
            callback()

    def _watch(self) -> None:
        """Set :attr:`ended` once no process of the run is alive."""
        assert self.run is not None
        while not self._closed.wait(WATCH_PERIOD):
            if not self.run.alive():
                with self._end_lock:
                    self.ended.set()
                    callback = self._on_end
                if callback is not None:
                    callback()
                return

    def _wait_joined(self, count: int) -> None:
        """Wait until a session is open to each of the run's ``count`` processes; UserError
        when none opens (the credentials are refused, or the run just ended)."""
        if wait_joined(self.session, count, JOIN_TIMEOUT) == 0:
            self.close()
            graph = self.run.graph if self.run else self.prefix
            raise UserError(
                f"error: cannot join graph `{graph}`: none of its {count} processes accepted "
                f"this observer's session within {JOIN_TIMEOUT:g} s (access refused, or the "
                f"run is ending)"
            )

    def _codec(self) -> Codec:
        try:
            codec: Codec = self._local.codec
        except AttributeError:
            codec = self._local.codec = Codec()
        return codec

    def observed(self, sample: zenoh.Sample) -> Observed:
        """``sample`` decoded (any zenoh thread)."""
        key, now = str(sample.key_expr), time.monotonic()
        info = sample.source_info
        source = str(info.source_id.zid) if info is not None else ""
        parsed = parse_encoding(str(sample.encoding))
        type_name = parsed[2] if parsed else ""
        if sample.kind == zenoh.SampleKind.DELETE:
            return Observed(key, "end", None, type_name, 0, source, now)
        data = sample.payload.to_bytes()
        if (parsed and parsed[0] == POOL_MEDIA_TYPE) or data[:4] in (
            DESCRIPTOR_MAGIC,
            FORWARD_MAGIC,
        ):
            why = "a frame-pool descriptor (only the graph's processes read it)"
            return Observed(key, "undecodable", None, type_name, len(data), source, now, why)
        try:
            msg = self._codec().decode(data)
        except Exception as exc:
            return Observed(key, "undecodable", None, type_name, len(data), source, now, str(exc))
        return Observed(key, "sample", msg, type(msg).__name__, len(data), source, now)

    def subscribe(self, on_sample: Callable[[Observed], None], key_expr: str | None = None) -> None:
        """Call ``on_sample`` for every sample and end of stream under ``key_expr`` (default:
        each key this observer may read, else ``P/*/*``). A wildcard expression becomes one
        subscription per readable key it holds (zenoh's rules refuse a subscription wider than
        the keys an observer may read)."""
        observed = self.observed
        exprs = [key_expr] if key_expr else self.keys or [f"{self.prefix}/*/*"]
        if key_expr and self.keys is not None and ("*" in key_expr or "$" in key_expr):
            wide = zenoh.KeyExpr(key_expr)  # one subscriber per readable key it holds
            exprs = [k for k in self.keys if wide.includes(zenoh.KeyExpr(k))]
        ended = self.ended

        def deliver(sample: zenoh.Sample) -> None:
            if not ended.is_set():  # never a sample of another run on the same endpoints
                on_sample(observed(sample))

        for expr in exprs:
            self._subs.append(self.session.declare_subscriber(expr, deliver))

    def producers(self, timeout: float = 1.0) -> dict[str, str]:
        """Zenoh session id of each process of the graph whose liveliness token is up."""
        found: dict[str, str] = {}
        for reply in self.session.liveliness().get(alive_pattern(self.prefix), timeout=timeout):
            ok = getattr(reply, "ok", None)
            token = parse_alive_key(str(ok.key_expr)) if ok is not None else None
            if token is not None:
                found[token.process] = token.session
        return found

    def close(self) -> None:
        self._closed.set()
        for sub in self._subs:
            with contextlib.suppress(Exception):  # the session may be closing already
                sub.undeclare()
        self._subs.clear()
        self.session.close()
