"""``umbra run GRAPH`` for a graph split over processes: start, watch and stop one OS process each.

Every process of the graph runs as ``umbra run GRAPH --process NAME`` in a child process. The
launcher gives each a free loopback endpoint (process i listens on its own port and connects to
the processes before it: peers do not route for each other; ``tls/`` endpoints when the zenoh
configuration sets up TLS, e.g. a folder written by ``umbra keys``), per-run credentials and the
graph's access rules (``umbra.runtime.links.auth``; not with ``--insecure``), prefixes their output
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

Run ID: each run has one (:func:`run_identity`: ``--run-id``, else a new one), said on start and
given to every process (``--run-id``), which writes it into its run file
(``umbra.runtime.links.runs``): the run's live server and the observers (``umbra topics --run ID``)
find this run's processes by it, never another run's of the same graph.

When a child ends, the others are told first (``finish`` or ``abort``: a starved launcher has
taken seconds over what comes next); then the ``/dev/shm`` files it left (its frame pools, its host
marker, zenoh's segments it mapped) are removed (``umbra.runtime.links.shm_sweep``), and then its
end is said.

Clock: sim time cannot be shared between processes, so a split graph runs on the real clock; a
graph that declares ``clock: sim`` runs on the real clock with a notice, and ``--clock sim`` with a
split run is an error (use ``--single-process`` to run on sim time).
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import IO, Any

from umbra.connectors.errors import UserError
from umbra.runtime.child_summaries import Child, cause_of, reason_of, write_summaries
from umbra.runtime.graph.plan import GraphPlan
from umbra.runtime.link_settings import checked_endpoints, graph_links_origin, zenoh_config_file
from umbra.runtime.links.auth import RunCredentials
from umbra.runtime.links.config import (
    Endpoints,
    check_config_file,
    free_loopback_ports,
    loopback_mesh,
)
from umbra.runtime.links.config_facts import config_facts
from umbra.runtime.links.control_line import FINISH_GRACE, ControlCommand, ControlLine
from umbra.runtime.links.end_ack import END_ACK_S
from umbra.runtime.links.exposure import check_exposure, config_for
from umbra.runtime.links.runs import BY_HAND, checked_run_id, new_run_id
from umbra.runtime.links.shm_sweep import mapped_segments, remove_orphans
from umbra.runtime.ros2.run_args import child_args, ros2_options
from umbra.runtime.run_one import run_one
from umbra.runtime.scheduler import INTERRUPTED

#: Seconds a process has to stop once told (abort), before SIGTERM; SIGKILL after as long again.
STOP_GRACE = 5.0
#: Extra seconds given to a process told to ``finish``: it drains its inputs first, and waits for
#: its consumers to read its ends of stream when it closes.
FINISH_EXTRA = FINISH_GRACE + END_ACK_S
_POLL = 0.02
#: Seconds between looks at the shared memory each child maps (``umbra.runtime.links.shm_sweep``):
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


def run_identity(plan: GraphPlan, args: argparse.Namespace) -> str:
    """This run's ID: ``args.run_id`` (``--run-id``) when given and no live run of this user
    holds it (else UserError), otherwise a new one (``umbra.runtime.links.runs.new_run_id``).
    A process started by hand (``--process``) takes ``--run-id`` as it is (the other processes
    of its run hold it too), else ``by-hand``."""
    given: str | None = getattr(args, "run_id", None)
    if getattr(args, "process", None):
        return checked_run_id(given) if given else BY_HAND
    if not given:
        return new_run_id(plan.spec.name)
    from umbra.runtime.links.observe import find_run

    running = find_run(checked_run_id(given))
    if running is not None:
        raise UserError(
            f"--run-id: expected an ID no live run holds, found `{given}` held by run "
            f"{running.describe()}; give another, or leave --run-id out for a new one"
        )
    return given


def servo_processes(plan: GraphPlan) -> set[str]:
    """Processes holding a safety guard or a drive that requires one: stopped first."""
    return {
        m.process
        for m in plan.modules.values()
        if m.cls.SAFETY_GUARD or any(d.requires_guard for d in m.input_decls.values())
    }


# -- supervision ---------------------------------------------------------------------------------
class Supervisor:
    """Starts every process of a split graph and sees the run through (see module docstring)."""

    def __init__(
        self, plan: GraphPlan, args: argparse.Namespace, duration: float | None, out: Path
    ) -> None:
        self.plan, self.args, self.duration, self.out = plan, args, duration, out
        self.children: list[Child] = []
        self._lock = threading.Lock()
        self._signals: list[str] = []
        self._pumps: list[threading.Thread] = []
        self.credentials: RunCredentials | None = None
        #: this run's ID (:func:`run_identity`), given to every process
        self.run_id = getattr(args, "run_id", None) or run_identity(plan, args)
        self.started = time.time()  #: when the run started [s since the epoch]

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

    def _pump(self, child: Child, pipe: IO[bytes], stream: IO[str], prefix: bytes) -> None:
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
            "umbra.runtime.cli.main",
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
            "--run-id",
            self.run_id,
            "--run-started",
            repr(self.started),
        ]
        if self.duration is not None:
            cmd += ["--duration", repr(float(self.duration))]
        for item in args.set:
            cmd += ["--set", item]
        for e in endpoints.listen:
            cmd += ["--listen", e]
        for e in endpoints.connect:
            cmd += ["--connect", e]
        config_file = zenoh_config_file(plan, args)
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
        if getattr(args, "attended", False):
            cmd.append("--attended")
        if getattr(args, "cpu_latency_us", None) is not None:
            cmd += ["--cpu-latency-us", str(args.cpu_latency_us)]
        if args.quiet:
            cmd.append("--quiet")
        if plan.spec.record.enabled:  # each process records its part (umbra.runtime.recording)
            cmd.append("--record")
            if getattr(args, "record_images", None):
                cmd += ["--record-images", args.record_images]
            if getattr(args, "record_format", None):
                cmd += ["--record-format", args.record_format]
        cmd += child_args(ros2_options(plan, args))  # each process's own ROS 2 node
        return cmd

    def _start(self) -> None:
        plan, args = self.plan, self.args
        names = plan.populated_processes
        self.say(f"run ID {self.run_id}")
        for p in plan.processes:
            if p not in names:
                self.say(f"process `{p}` has no modules; not started")
        config_file = zenoh_config_file(plan, args)
        files = [config_for(config_file, name) for name in names] if config_file else []
        facts = [config_facts(file) for file in files]  # the launcher's one parse of each
        tls = bool(facts) and facts[0].tls
        mesh = loopback_mesh(names, free_loopback_ports(len(names)), "tls" if tls else "tcp")
        extra_listen = checked_endpoints(args.listen, "--listen") or checked_endpoints(
            plan.spec.links.listen, "links.listen"
        )
        extra_connect = checked_endpoints(args.connect, "--connect") or checked_endpoints(
            plan.spec.links.connect, "links.connect"
        )
        insecure = bool(getattr(args, "insecure", False))
        given = args.listen or args.connect
        check_exposure(
            extra_listen,
            extra_connect,
            insecure,
            "--listen/--connect" if given else graph_links_origin(plan),
        )
        for file, parsed in zip(files, facts, strict=True):  # every process's file: say so now
            check_config_file(file, parsed.config)
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
            child = Child(name, endpoints, popen, name in servo)
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
    def _tell(
        self, child: Child, command: ControlCommand, reason: str, finished: str | None = None
    ) -> None:
        if not child.running or child.told_at is not None:
            return
        child.told_at, child.told = time.monotonic(), command
        line = ControlLine(command, reason, finished).encode()
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
            grace = STOP_GRACE + (FINISH_EXTRA if child.told is ControlCommand.FINISH else 0.0)
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
        write_summaries(self.plan, self.out, self.children, code, reason, started, self.run_id)
        if self.plan.spec.record.enabled:
            from umbra.runtime.recording.merge import merge_run

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
            ended = [c for c in self.children if c.running and c.popen.poll() is not None]
            for child in ended:
                child.code = child.popen.returncode
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
                        reason = f"process `{child.name}` finished: {reason_of(self.out, child)}"
                        verdict = (0, reason)
                        for other in self.children:
                            self._tell(other, ControlCommand.FINISH, reason, child.name)
                    continue
                if verdict is not None and verdict[0] != 0:
                    continue  # stopped as told, or died while stopping: the first cause stands
                if child.told is ControlCommand.ABORT:
                    continue
                cause = cause_of(self.out, child)
                code = 2 if child.code == 2 else 1
                verdict = (code, f"process `{child.name}` {cause}")
                abort_rest_at = self._abort(verdict[1], now)
            if abort_rest_at is not None and (
                now >= abort_rest_at or not any(c.running for c in self.children if c.servo)
            ):
                for child in self.children:
                    if child.told is not ControlCommand.ABORT:
                        child.told_at = None  # a finishing process is now aborted
                        self._tell(
                            child, ControlCommand.ABORT, verdict[1] if verdict else "stopped"
                        )
                abort_rest_at = None
            # what a loaded machine makes slow (reading /proc, the files) comes after the others
            # were told: the run's end reaches them at once
            for child in ended:
                self._say_ended(child)
            if now >= next_look:  # the shared memory each child maps, for when it dies
                next_look = now + SHM_LOOK_PERIOD
                for child in self.children:
                    if child.running:
                        child.segments |= mapped_segments(child.popen.pid)
            if not any(c.running for c in self.children):
                assert verdict is not None
                return verdict
            self._escalate(now)
            time.sleep(_POLL)

    def _say_ended(self, child: Child) -> None:
        """Say that ``child`` ended, once its shared memory is gone (nothing of it is left once
        the end is said)."""
        rc = child.code
        assert rc is not None
        how = f"exit {rc}" if rc >= 0 else cause_of(self.out, child)
        removed = remove_orphans(child.segments)
        self.say(f"process `{child.name}` ended ({how})")
        if removed and rc != 0:
            self.say(f"removed {removed} shared-memory files of dead processes")

    def _abort(self, reason: str, now: float) -> float:
        """Tell the servo side to stop now; the rest once it has (or after STOP_GRACE)."""
        for child in self.children:
            if child.servo:
                child.told_at = None if child.told is ControlCommand.FINISH else child.told_at
                self._tell(child, ControlCommand.ABORT, reason)
        return now if not any(c.servo and c.running for c in self.children) else now + STOP_GRACE
