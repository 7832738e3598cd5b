"""``umbra run GRAPH`` for a graph split over processes: start, watch and stop one OS process each.

Every process of the graph runs as ``umbra run GRAPH --process NAME`` in a child process. The
launcher gives each a free loopback endpoint (process i listens on its own port and connects to
the processes before it: peers do not route for each other; ``tls/`` endpoints when the zenoh
configuration sets up TLS, e.g. a folder written by ``umbra keys``), per-run credentials and the
graph's access rules (``runtime.links.auth``; not with ``--insecure``), prefixes their output
lines with ``[NAME]``, and supervises them:

* a process that ends normally (its duration, or a module asked to stop with status 0) ends the
  run: the others are told to ``finish`` — each handles what its inputs already sent, then stops;
* a process that fails or dies (exit status not 0, a signal, a crash) fails the run: the others
  are told to ``abort``, the servo side first (processes holding a safety guard or a guarded
  drive), which zeroes its outputs before it stops; then the rest. ``umbra run`` exits 1 naming
  the process and the cause;
* Ctrl-C (SIGINT) or SIGTERM stops every process in the same order; exit status 130.

A process that does not stop within ``STOP_GRACE`` seconds of being told gets SIGTERM, then
SIGKILL. Each process writes ``summary-NAME.json`` (the launcher writes it for a process that died
without one) and the launcher writes ``summary.json`` for the whole run.

When a child ends, the ``/dev/shm`` files it left (its frame pools, its host marker, zenoh's
segments it mapped) are removed at once (``runtime.links.shm_sweep``).

Clock: sim time cannot be shared between processes, so a split graph runs on the real clock; a
graph that declares ``clock: sim`` runs on the real clock with a notice, and ``--clock sim`` with a
split run is an error (use ``--single-process`` to run on sim time).
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from connectors.errors import UserError
from runtime.graph.plan import GraphPlan
from runtime.hints import did_you_mean
from runtime.links.auth import RunCredentials
from runtime.links.config import (
    Endpoints,
    check_config_file,
    check_endpoint,
    default_mesh,
    file_endpoints,
    free_loopback_ports,
    loopback_mesh,
)
from runtime.links.exposure import (
    authenticates,
    check_exposure,
    config_for,
    routed_mode,
    uses_tls,
)
from runtime.links.host_auth import host_credentials
from runtime.links.shm_sweep import mapped_segments, remove_orphans
from runtime.links.stats import link_lines
from runtime.realtime import latency_limit
from runtime.scheduler import INTERRUPTED

#: Seconds a supervised process may wait for its consumers to come up.
READY_TIMEOUT = 30.0
#: Seconds a process has to stop once told (abort), before SIGTERM; SIGKILL after as long again.
STOP_GRACE = 5.0
#: Extra seconds given to a process told to ``finish`` (it drains its inputs first).
FINISH_EXTRA = 6.0
_POLL = 0.02
#: Seconds between looks at the shared memory each child maps (``runtime.links.shm_sweep``):
#: a segment mapped less than this before a child dies may be missed (a look costs ~1.5 ms).
SHM_LOOK_PERIOD = 0.5


def main(
    plan: GraphPlan, args: argparse.Namespace, clock: str, duration: float | None, out: Path
) -> int:
    """Run a split graph: every process under supervision, or ``args.process`` alone."""
    clock = split_clock(plan, args, clock)
    if getattr(args, "process", None):
        return run_one(plan, args, clock, duration, out)
    return Supervisor(plan, args, duration, out).run()


def split_clock(plan: GraphPlan, args: argparse.Namespace, clock: str) -> str:
    """The clock of a split run: always real (see the module docstring)."""
    if clock == "real":
        return clock
    if getattr(args, "clock", None) == "sim":
        raise UserError(
            "--clock sim: a graph split over processes runs on the real clock (sim time cannot "
            "be shared between processes); use --single-process to run it on sim time"
        )
    if not getattr(args, "supervised", False):
        print(
            f"umbra run: note: graph `{plan.spec.name}` declares clock: sim; split over "
            f"processes it runs on the real clock (use --single-process for sim time)",
            file=sys.stderr,
        )
    return "real"


def servo_processes(plan: GraphPlan) -> set[str]:
    """Processes holding a safety guard or a drive that requires one: stopped first."""
    return {
        m.process
        for m in plan.modules.values()
        if m.cls.SAFETY_GUARD or any(d.requires_guard for d in m.input_decls.values())
    }


def _config_file(plan: GraphPlan, args: argparse.Namespace) -> str | None:
    if getattr(args, "zenoh_config", None):
        return str(args.zenoh_config)
    if plan.spec.links.zenoh_config:
        path = Path(plan.spec.links.zenoh_config)
        if not path.is_absolute():  # relative to the graph file
            path = Path(plan.spec.file).parent / path
        return str(path)
    return None


def _graph_links(plan: GraphPlan) -> str:
    """``FILE:LINE`` of the graph's ``links:`` section (where its endpoints come from)."""
    loc = plan.spec.links.loc
    return f"{loc.file}:{loc.line}" if loc is not None else str(plan.spec.file)


def _endpoints(values: list[str], where: str) -> list[str]:
    return [check_endpoint(v, where) for v in values]


# -- one process ---------------------------------------------------------------------------------
def run_one(
    plan: GraphPlan, args: argparse.Namespace, clock: str, duration: float | None, out: Path
) -> int:
    """``umbra run GRAPH --process NAME``: one process with its links (by hand or supervised).

    Endpoints: ``--listen``/``--connect`` when given, else the graph's ``links:``, else those of
    the zenoh configuration file, else a fixed loopback mesh (process i of the graph listens on
    tcp/127.0.0.1:7447+i and connects to the ones before it), so processes started by hand on one
    host find each other with no flags.

    Credentials: the launcher's (``--link-auth``), else those of the zenoh configuration file when
    it authenticates on its own (TLS, a password), else, unless ``--insecure``, those derived
    from this user's secret (``runtime.links.host_auth``), shared by every process of the graph
    this user starts by hand on this host."""
    import logging

    from runtime.links.process import ProcessOptions, run_linked_process

    name = args.process
    have = plan.populated_processes
    if name not in have:
        raise UserError(
            f"--process: graph `{plan.spec.name}` has no process `{name}` with "
            f"modules (processes: {', '.join(have)}){did_you_mean(name, have)}"
        )
    config_file = _config_file(plan, args)
    if config_file:
        config_file = config_for(config_file, name)
    endpoints = Endpoints(
        _endpoints(args.listen, "--listen"), _endpoints(args.connect, "--connect")
    )
    origin = "--listen/--connect"
    if endpoints.empty:
        endpoints = Endpoints(
            _endpoints(plan.spec.links.listen, "links.listen"),
            _endpoints(plan.spec.links.connect, "links.connect"),
        )
        origin = _graph_links(plan)
    if endpoints.empty and config_file:
        endpoints = file_endpoints(config_file)
        origin = config_file
    if endpoints.empty:
        endpoints = default_mesh(have)[name]
    insecure = bool(getattr(args, "insecure", False))
    check_exposure(endpoints.listen, endpoints.connect, insecure, origin)
    supervised = bool(getattr(args, "supervised", False))
    link_auth = getattr(args, "link_auth", None)
    auth = None
    routed = routed_mode(config_file)
    if routed and not (link_auth or insecure or authenticates(config_file)):
        logging.getLogger("umbra").warning(
            "process `%s`: %s: mode `%s` links through a zenoh router, which does not hold the "
            "graph's credentials: links are not authenticated (set TLS or usrpwd up in that file)",
            name,
            config_file,
            routed,
        )
    elif not (link_auth or insecure or authenticates(config_file)):
        auth = host_credentials(plan, name)
        logging.getLogger("umbra").info(
            "process `%s`: links authenticated with this user's secret %s (only the graph's "
            "processes this user starts on this host can join; --insecure: anyone)",
            name,
            auth["secret_file"],
        )
    options = ProcessOptions(
        process=name,
        output_dir=out,
        endpoints=endpoints,
        clock=clock,
        duration=duration,
        zenoh_config=config_file,
        link_auth=link_auth,
        auth=auth,
        link_checks=not getattr(args, "unchecked_links", False),
        ready_timeout=READY_TIMEOUT if supervised else None,
        quiet=args.quiet,
        cpu_latency_us=latency_limit(
            plan.spec.cpu_latency_us, name, getattr(args, "cpu_latency_us", None)
        ),
        publish_all=bool(getattr(args, "publish_all", False)),
    )
    result = run_linked_process(
        plan, options, control=sys.stdin if supervised else None, log=logging.getLogger("umbra")
    )
    if not args.quiet:
        print(result.table(), file=sys.stderr)
        for line in link_lines(result.extra.get("links", {})):
            print(line, file=sys.stderr)
        print(f"summary written to {out / f'summary-{name}.json'}", file=sys.stderr)
    return result.exit_code


# -- supervision ---------------------------------------------------------------------------------
@dataclass
class _Child:
    name: str
    endpoints: Endpoints
    popen: subprocess.Popen[bytes]
    servo: bool
    tail: deque[str] = field(default_factory=lambda: deque(maxlen=8))
    told_at: float | None = None
    told: str = ""
    termed: bool = False
    code: int | None = None
    segments: set[str] = field(default_factory=set)  #: /dev/shm files it was seen to map

    @property
    def running(self) -> bool:
        return self.code is None


class Supervisor:
    """Starts every process of a split graph and sees the run through (see module docstring)."""

    def __init__(
        self, plan: GraphPlan, args: argparse.Namespace, duration: float | None, out: Path
    ) -> None:
        self.plan, self.args, self.duration, self.out = plan, args, duration, out
        self.children: list[_Child] = []
        self._lock = threading.Lock()
        self._signals: list[str] = []
        self._pumps: list[threading.Thread] = []
        self.credentials: RunCredentials | None = None

    # -- output ------------------------------------------------------------------------------
    def say(self, text: str) -> None:
        self._write(sys.stderr, f"umbra run: {text}\n".encode())

    def _write(self, stream: IO[str], data: bytes) -> None:
        with self._lock:
            buffer = getattr(stream, "buffer", None)
            if buffer is not None:
                buffer.write(data)
            else:
                stream.write(data.decode("utf-8", "replace"))
            stream.flush()

    def _pump(self, child: _Child, pipe: IO[bytes], stream: IO[str], prefix: bytes) -> None:
        for line in iter(pipe.readline, b""):
            if stream is sys.stderr:
                child.tail.append(line.decode("utf-8", "replace").rstrip())
            self._write(stream, prefix + (line if line.endswith(b"\n") else line + b"\n"))
        pipe.close()

    # -- start ---------------------------------------------------------------------------------
    def _command(self, name: str, endpoints: Endpoints) -> list[str]:
        args, plan = self.args, self.plan
        cmd = [
            sys.executable,
            "-m",
            "runtime.cli.main",
            "run",
            str(args.graph),
            "--process",
            name,
            "--supervised",
            "--clock",
            "real",
            "--out",
            str(self.out),
            "--prefix",
            plan.key_prefix,
        ]
        if self.duration is not None:
            cmd += ["--duration", repr(float(self.duration))]
        for item in args.set:
            cmd += ["--set", item]
        for e in endpoints.listen:
            cmd += ["--listen", e]
        for e in endpoints.connect:
            cmd += ["--connect", e]
        config_file = _config_file(plan, args)
        if config_file:
            cmd += ["--zenoh-config", config_file]
        if self.credentials is not None:
            cmd += ["--link-auth", str(self.credentials.files[name])]
        if getattr(args, "insecure", False):
            cmd.append("--insecure")
        if getattr(args, "unchecked_links", False):
            cmd.append("--unchecked-links")
        if getattr(args, "publish_all", False):
            cmd.append("--publish-all")
        if getattr(args, "cpu_latency_us", None) is not None:
            cmd += ["--cpu-latency-us", str(args.cpu_latency_us)]
        if args.quiet:
            cmd.append("--quiet")
        if plan.spec.record.enabled:  # each process records its part (runtime.recording)
            cmd.append("--record")
            if getattr(args, "record_images", None):
                cmd += ["--record-images", args.record_images]
        return cmd

    def _start(self) -> None:
        plan, args = self.plan, self.args
        names = plan.populated_processes
        for p in plan.processes:
            if p not in names:
                self.say(f"process `{p}` has no modules; not started")
        config_file = _config_file(plan, args)
        tls = uses_tls(config_for(config_file, names[0]) if config_file else None)
        mesh = loopback_mesh(names, free_loopback_ports(len(names)), "tls" if tls else "tcp")
        extra_listen = _endpoints(args.listen, "--listen") or _endpoints(
            plan.spec.links.listen, "links.listen"
        )
        extra_connect = _endpoints(args.connect, "--connect") or _endpoints(
            plan.spec.links.connect, "links.connect"
        )
        insecure = bool(getattr(args, "insecure", False))
        given = args.listen or args.connect
        check_exposure(
            extra_listen,
            extra_connect,
            insecure,
            "--listen/--connect" if given else _graph_links(plan),
        )
        if config_file:
            for name in names:  # every process has a file zenoh accepts: say so now
                check_config_file(config_for(config_file, name))
        if not insecure:
            # a run served live (--foxglove): the live server may send parameter changes
            tuner = getattr(self.args, "tuner_password", None)
            self.credentials = RunCredentials(plan, tuner_password=tuner)
        servo = servo_processes(plan)
        env = dict(os.environ, PYTHONUNBUFFERED="1")
        root = str(Path(__file__).resolve().parents[1])
        env["PYTHONPATH"] = os.pathsep.join(p for p in (root, env.get("PYTHONPATH", "")) if p)
        width = max(len(n) for n in names)
        for i, name in enumerate(names):
            endpoints = Endpoints(
                mesh[name].listen + (extra_listen if i == 0 else []),
                mesh[name].connect + extra_connect,
            )
            (self.out / f"summary-{name}.json").unlink(missing_ok=True)
            popen = subprocess.Popen(
                self._command(name, endpoints),
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
                env=env,
                start_new_session=True,
            )
            child = _Child(name, endpoints, popen, name in servo)
            self.children.append(child)
            prefix = f"[{name}]".ljust(width + 3).encode()
            for pipe, stream in ((popen.stdout, sys.stdout), (popen.stderr, sys.stderr)):
                t = threading.Thread(
                    target=self._pump,
                    args=(child, pipe, stream, prefix),
                    name=f"umbra-pump-{name}",
                    daemon=True,
                )
                t.start()
                self._pumps.append(t)
            role = " (servo side)" if child.servo else ""
            self.say(
                f"started process `{name}`{role}, pid {popen.pid}, "
                f"listening on {', '.join(endpoints.listen)}"
            )

    # -- commands --------------------------------------------------------------------------------
    def _tell(self, child: _Child, command: str, reason: str) -> None:
        if not child.running or child.told_at is not None:
            return
        child.told_at, child.told = time.monotonic(), command
        line = f"{command} {' '.join(reason.split())}\n".encode()
        try:
            assert child.popen.stdin is not None
            child.popen.stdin.write(line)
            child.popen.stdin.flush()
        except (BrokenPipeError, OSError):
            pass

    def _escalate(self, now: float) -> None:
        for child in self.children:
            if not child.running or child.told_at is None:
                continue
            grace = STOP_GRACE + (FINISH_EXTRA if child.told == "finish" else 0.0)
            waited = now - child.told_at
            if waited > 2 * grace:
                child.popen.kill()
            elif waited > grace and not child.termed:
                child.termed = True
                self.say(f"process `{child.name}` did not stop within {grace:g} s; sending SIGTERM")
                child.popen.terminate()

    def _on_signal(self, signum: int, frame: Any) -> None:
        self._signals.append(signal.Signals(signum).name)

    # -- the run -------------------------------------------------------------------------------
    def run(self) -> int:
        self.out.mkdir(parents=True, exist_ok=True)
        old = {}
        if threading.current_thread() is threading.main_thread():
            # Ctrl-Z (SIGTSTP) too: a suspended run cannot watch the arm, so it stops safely
            stops = (signal.SIGINT, signal.SIGTERM, signal.SIGTSTP)
            old = {s: signal.signal(s, self._on_signal) for s in stops}
        started = time.time()
        try:
            self._start()
            code, reason = self._supervise()
        finally:
            for child in self.children:
                if child.running:
                    child.popen.kill()
                    child.code = child.popen.wait()
            for t in self._pumps:
                t.join(timeout=2.0)
            if self.credentials is not None:
                self.credentials.close()
            for s, handler in old.items():
                signal.signal(s, handler)
        self._write_summaries(code, reason, started)
        if self.plan.spec.record.enabled:
            from runtime.recording.merge import merge_run

            self.say(merge_run(self.plan, self.out, [c.name for c in self.children]))
        self.say(reason if code in (0, INTERRUPTED) else f"failed: {reason}")
        self.say(f"summary written to {self.out}")
        return code

    def _supervise(self) -> tuple[int, str]:
        verdict: tuple[int, str] | None = None
        abort_rest_at: float | None = None
        interrupts_seen = 0
        next_look = time.monotonic() + SHM_LOOK_PERIOD
        while True:
            now = time.monotonic()
            ended = []
            if now >= next_look:  # the shared memory each child maps, for when it dies
                next_look = now + SHM_LOOK_PERIOD
                for child in self.children:
                    if child.running:
                        child.segments |= mapped_segments(child.popen.pid)
            for child in self.children:
                if child.running and (rc := child.popen.poll()) is not None:
                    child.code = rc
                    ended.append(child)
                    how = f"exit {rc}" if rc >= 0 else self._cause(child)
                    self.say(f"process `{child.name}` ended ({how})")
                    removed = remove_orphans(child.segments)
                    if removed and rc != 0:
                        self.say(f"removed {removed} shared-memory files of dead processes")
            if len(self._signals) > interrupts_seen:
                interrupts_seen = len(self._signals)
                if verdict is None or verdict[0] == 0:
                    verdict = (
                        INTERRUPTED,
                        f"interrupted by {self._signals[0]}; every process "
                        f"stopped, servo side first",
                    )
                    abort_rest_at = self._abort(verdict[1], now)
                elif interrupts_seen > 1:
                    self.say("interrupted again: terminating every process now")
                    for child in self.children:
                        if child.running:
                            child.popen.terminate()
            for child in ended:
                if child.code == 0:
                    if verdict is None:
                        reason = f"process `{child.name}` finished: {self._reason(child)}"
                        verdict = (0, reason)
                        for other in self.children:
                            self._tell(other, "finish", reason)
                    continue
                if verdict is not None and verdict[0] != 0:
                    continue  # stopped as told, or died while stopping: the first cause stands
                if child.told == "abort":
                    continue
                cause = self._cause(child)
                code = 2 if child.code == 2 else 1
                verdict = (code, f"process `{child.name}` {cause}")
                abort_rest_at = self._abort(verdict[1], now)
            if abort_rest_at is not None and (
                now >= abort_rest_at or not any(c.running for c in self.children if c.servo)
            ):
                for child in self.children:
                    if child.told != "abort":
                        child.told_at = None  # a finishing process is now aborted
                        self._tell(child, "abort", verdict[1] if verdict else "stopped")
                abort_rest_at = None
            if not any(c.running for c in self.children):
                assert verdict is not None
                return verdict
            self._escalate(now)
            time.sleep(_POLL)

    def _abort(self, reason: str, now: float) -> float:
        """Tell the servo side to stop now; the rest once it has (or after STOP_GRACE)."""
        for child in self.children:
            if child.servo:
                child.told_at = None if child.told == "finish" else child.told_at
                self._tell(child, "abort", reason)
        return now if not any(c.servo and c.running for c in self.children) else now + STOP_GRACE

    # -- causes and summaries ------------------------------------------------------------------
    def _summary(self, child: _Child) -> dict[str, Any] | None:
        path = self.out / f"summary-{child.name}.json"
        try:
            return json.loads(path.read_text())
        except (OSError, ValueError):
            return None

    def _reason(self, child: _Child) -> str:
        summary = self._summary(child)
        if summary and summary.get("reason"):
            return str(summary["reason"])
        return child.tail[-1] if child.tail else "no reason given"

    def _cause(self, child: _Child) -> str:
        rc = child.code
        assert rc is not None
        if rc < 0:
            try:
                name = signal.Signals(-rc).name
            except ValueError:
                name = f"signal {-rc}"
            return f"died: killed by {name}"
        return f"failed (exit {rc}): {self._reason(child)}"

    def _write_summaries(self, code: int, reason: str, started: float) -> None:
        processes = []
        for child in self.children:
            summary = self._summary(child)
            if summary is None:  # died before writing one
                summary = {
                    "process": child.name,
                    "exit_code": child.code,
                    "reason": self._cause(child) if child.code else "no summary written",
                    "modules": [],
                }
                path = self.out / f"summary-{child.name}.json"
                path.write_text(json.dumps(summary, indent=2))
            processes.append(
                {
                    "process": child.name,
                    "pid": child.popen.pid,
                    "exit_code": child.code,
                    "reason": summary.get("reason", ""),
                    "servo_side": child.servo,
                    "listen": child.endpoints.listen,
                    "connect": child.endpoints.connect,
                }
            )
        whole = {
            "graph": self.plan.spec.name,
            "mode": "split",
            "exit_code": code,
            "reason": reason,
            "wall_time_s": round(time.time() - started, 3),
            "key_prefix": self.plan.key_prefix,
            "processes": processes,
        }
        (self.out / "summary.json").write_text(json.dumps(whole, indent=2))
