"""Fixtures for link tests: probe modules registered by entry point, and running ``umbra``."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from tests.links.pairs import Pair, open_pair
from tests.poll import wait_for
from umbra.runtime.graph.check import load_graph
from umbra.runtime.graph.plan import GraphPlan

REPO = Path(__file__).resolve().parents[2]
PROBES = {
    "LinkWatch": "tests.links.probes:LinkWatch",
    "ProbeGuard": "tests.links.probes:ProbeGuard",
    "Boom": "tests.links.probes:Boom",
    "ProbeTwist": "tests.links.probes:ProbeTwist",
    "ArmWatch": "tests.links.probes:ArmWatch",
    "Ballast": "tests.links.probes:Ballast",
}


def watched_counter_graph(name: str) -> str:
    """A counter in process `umbra` (100 Hz) watched over a link by a LinkWatch in `smart`."""
    return f"""
graph: {name}
clock: real
processes: {{umbra: {{}}, smart: {{}}}}
modules:
  counter: {{type: Counter, process: umbra, rate: 100}}
  watch: {{type: LinkWatch, process: smart, rate: 200, params: {{timeout: 0.1}}}}
connections:
  - counter.count -> watch.input
"""


def guarded_arm_graph(
    name: str, extra_process: bool = False, realtime_priority: int | None = None
) -> str:
    """The servo path of the split pick-up without vision: a constant twist (zero) from process
    `umbra` through REG_VEL, ROTATE_KIN, WOLVERINE_KIN to a simulated Puma in `smart`, watched
    by an ArmWatch at the servo rate (100 Hz). ``extra_process``: a third process `ui` of the
    graph (an insider) whose only output is a counter watched in `smart`. ``realtime_priority``:
    the `smart` process's threads under SCHED_FIFO at that priority (the graph's own setting)."""
    ui = (
        "  tick: {type: Counter, process: ui, rate: 10}\n"
        "  ticks: {type: LinkWatch, process: smart, rate: 20, params: {timeout: 1.0}}\n"
        if extra_process
        else ""
    )
    ui_link = "  - tick.count -> ticks.input\n" if extra_process else ""
    smart = f"{{realtime_priority: {realtime_priority}}}" if realtime_priority else "{}"
    ui_process = ", ui: {}" if extra_process else ""
    processes = f"{{umbra: {{}}, smart: {smart}{ui_process}}}"
    return f"""
graph: {name}
clock: real
processes: {processes}
frames:
  flange->tool: {{xyz: [0, 0, 0.14]}}
  tool->camera: {{xyz: [0, 0, -0.12]}}
modules:
  source: {{type: ProbeTwist, process: umbra, rate: 50}}
  register: {{type: REG_VEL, process: smart, rate: 100,
             params: {{timeout: 0.1, max_linear: 0.05, max_angular: 0.3}}}}
  rotate: {{type: ROTATE_KIN, process: smart}}
  kinematics: {{type: WOLVERINE_KIN, process: smart, params: {{tool_xyz: [0, 0, 0.14]}}}}
  joints: {{type: WOLVERINE_JNTS, process: smart, rate: 100,
           params: {{initial_q_deg: [14.482, 45.603, -182.743, 0.0, -42.86, -165.518]}}}}
  arm: {{type: ArmWatch, process: smart, rate: 100}}
{ui}connections:
  - source.twist -> register.command
  - register.twist -> rotate.camera_twist
  - rotate.tool_twist -> kinematics.tool_twist
  - kinematics.joint_rates -> joints.rates
  - joints.joint_state ~> kinematics.joint_state
  - joints.joint_state -> arm.joints
  - register.status -> arm.guard
{ui_link}"""


@pytest.fixture(scope="session")
def plugin_env(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    """Environment in which child processes see the probe modules, registered as a third-party
    package would register them (a dist-info with ``umbra.modules`` entry points)."""
    root = tmp_path_factory.mktemp("probe_plugin")
    dist = root / "umbra_link_probes-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: umbra-link-probes\nVersion: 0.1\n")
    lines = "".join(f"{name} = {target}\n" for name, target in PROBES.items())
    (dist / "entry_points.txt").write_text(f"[umbra.modules]\n{lines}")
    path = os.pathsep.join([str(root), str(REPO), os.environ.get("PYTHONPATH", "")])
    runtime_dir = tmp_path_factory.mktemp("xdg_runtime")  # link secrets of by-hand processes
    runtime_dir.chmod(0o700)
    return dict(
        os.environ,
        PYTHONPATH=path.rstrip(os.pathsep),
        PYTHONUNBUFFERED="1",
        XDG_RUNTIME_DIR=str(runtime_dir),
    )


@dataclass
class Running:
    """A running ``umbra`` command whose output lines are collected as they come."""

    popen: subprocess.Popen[str]
    stdout: list[str] = field(default_factory=list)
    stderr: list[str] = field(default_factory=list)
    threads: list[threading.Thread] = field(default_factory=list)

    def wait_for(self, text: str, timeout: float = 20.0) -> str:
        """The first stderr/stdout line containing ``text``; fails after ``timeout`` s, or at
        once when the process has ended without it."""

        def line() -> str:
            found = next((line for line in self.stderr + self.stdout if text in line), "")
            ended = self.popen.poll() is not None and all(not t.is_alive() for t in self.threads)
            assert found or not ended, f"ended with no line with {text!r}" + tail()
            return found

        def tail() -> str:
            return "; stderr:\n" + "\n".join(self.stderr[-40:])

        return wait_for(line, timeout, lambda: f"a line with {text!r}" + tail())

    def finish(self, timeout: float = 60.0) -> int:
        """The exit status. A process still running after ``timeout`` s is asked for its
        threads' stacks (SIGUSR1), killed, and the test fails with them and its output."""
        try:
            code = self.popen.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.popen.send_signal(signal.SIGUSR1)
            with contextlib.suppress(AssertionError):  # no dump: the output says what it can
                wait_for(lambda: any("most recent call first" in x for x in self.stderr), 5.0)
            self.popen.kill()
            self.popen.wait(timeout=10)
            for t in self.threads:
                t.join(timeout=5)
            raise AssertionError(
                f"still running {timeout:g} s after it was asked to stop; its output:\n"
                + "\n".join(self.stdout[-40:] + self.stderr[-300:])
            ) from None
        for t in self.threads:
            t.join(timeout=5)
        return code

    @property
    def text(self) -> str:
        return "\n".join(self.stdout + self.stderr)


def _collect(stream: object, into: list[str]) -> None:
    for line in stream:  # type: ignore[attr-defined]
        into.append(line.rstrip("\n"))


def start_umbra(
    env: dict[str, str], cwd: Path, *args: str, prefix: tuple[str, ...] = ()
) -> Running:
    """Start ``umbra ARGS...`` in ``cwd`` (optionally through a prefix command such as
    ``ip netns exec NS``), collecting its output lines as they come."""
    cmd = [*prefix, sys.executable, "-m", "umbra.runtime.cli.main", *args]
    popen = subprocess.Popen(
        cmd,
        cwd=cwd,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        stdin=subprocess.DEVNULL,
        text=True,
    )
    run = Running(popen)
    for stream, into in ((popen.stdout, run.stdout), (popen.stderr, run.stderr)):
        t = threading.Thread(target=_collect, args=(stream, into), daemon=True)
        t.start()
        run.threads.append(t)
    return run


def stop_all(runs: list[Running]) -> None:
    """Kill whatever is still running."""
    for run in runs:
        if run.popen.poll() is None:
            run.popen.kill()
            run.popen.wait()


@pytest.fixture
def umbra(plugin_env: dict[str, str], tmp_path: Path) -> Iterator[Callable[..., Running]]:
    """Start ``umbra ARGS...`` in ``tmp_path``; every process still running at the end is killed."""
    started: list[Running] = []

    def start(*args: str, prefix: tuple[str, ...] = ()) -> Running:
        run = start_umbra(plugin_env, tmp_path, *args, prefix=prefix)
        started.append(run)
        return run

    yield start
    stop_all(started)


def run_umbra(
    env: dict[str, str], cwd: Path, *args: str, timeout: float = 120.0
) -> subprocess.CompletedProcess[str]:
    """Run ``umbra ARGS...`` to completion in ``cwd``."""
    return subprocess.run(
        [sys.executable, "-m", "umbra.runtime.cli.main", *args],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
        stdin=subprocess.DEVNULL,
    )


@pytest.fixture
def counter_plan() -> GraphPlan:
    """``graphs/counter_split.yaml``: a counter in ``umbra`` feeding ``smart``."""
    return load_graph(str(REPO / "graphs" / "counter_split.yaml"))


@pytest.fixture
def pair(counter_plan: GraphPlan) -> Iterator[Pair]:
    """The producer and the consumer of ``counter_plan``, closed after the test."""
    p = open_pair(counter_plan)
    yield p
    p.producer.close()
    p.consumer.close()
