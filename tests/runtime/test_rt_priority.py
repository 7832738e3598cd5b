"""Real-time scheduling of a servo process: the graph setting, the threads it moves, the summary,
and a host that refuses."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from tests.runtime.fixtures import make_registry
from umbra.connectors import Input, Module
from umbra.connectors.messages import Scalar
from umbra.runtime import rt_priority
from umbra.runtime.graph.check import check_text
from umbra.runtime.rt_priority import BACKGROUND_POLICIES, RealtimePriority, priority_for
from umbra.runtime.scheduler import Scheduler, SchedulerOptions

ROOT = os.geteuid() == 0
needs_root = pytest.mark.skipif(not ROOT, reason="SCHED_FIFO needs root or CAP_SYS_NICE")

GRAPH = """
graph: rtprio
clock: {clock}
processes:
  umbra: {{}}
  smart: {{realtime_priority: {priority}}}
modules:
  src: {{type: Counter, process: umbra, rate: 100}}
  probe: {{type: PolicyProbe, process: smart}}
connections:
  - src.count -> probe.value
"""


class PolicyProbe(Module):
    """Records the scheduling policy of the thread each step runs on."""

    TYPE = "PolicyProbe"
    value = Input(Scalar, trigger=True)

    def start(self) -> None:
        self.policies: set[int] = set()

    def step(self, now: float) -> None:
        self.policies.add(os.sched_getscheduler(0))

    def summary(self) -> dict[str, object]:
        return {"policies": sorted(self.policies)}


def _registry():
    reg = make_registry()
    reg.add(PolicyProbe)
    return reg


def _policies() -> dict[int, int]:
    """Each live thread's scheduling policy (a thread that ends while listed is left out)."""
    policies = {}
    for tid in (int(t) for t in os.listdir("/proc/self/task")):
        try:
            policies[tid] = os.sched_getscheduler(tid)
        except ProcessLookupError:
            continue  # ended since it was listed
    return policies


def test_the_graph_asks_per_process_and_bad_values_are_refused_at_their_line() -> None:
    plan = check_text(GRAPH.format(clock="sim", priority=80), "rt.yaml", _registry())
    assert plan.spec.realtime_priority == {"smart": 80}
    assert priority_for(plan.spec.realtime_priority, "smart") == 80
    assert priority_for(plan.spec.realtime_priority, "umbra") is None
    assert priority_for(plan.spec.realtime_priority, None) == 80  # one process: the highest
    for bad in ("0", "100", "high", "true", "50.5"):
        with pytest.raises(Exception) as err:
            check_text(GRAPH.format(clock="sim", priority=bad), "rt.yaml", _registry())
        assert "rt.yaml:6:" in str(err.value)
        assert "realtime_priority of process `smart` must be a whole number from 1 to 99" in str(
            err.value
        )


@needs_root
def test_every_thread_runs_under_sched_fifo_while_held_and_returns_after() -> None:
    started = threading.Event()
    stop = threading.Event()

    def worker() -> None:  # a thread that exists before, as zenoh's do
        started.set()
        stop.wait(5)

    thread = threading.Thread(target=worker, daemon=True)
    thread.start()
    started.wait(5)
    before = _policies()  # a zenoh session of an earlier test may have threads of its own policy
    assert before[threading.get_native_id()] == os.SCHED_OTHER
    priority = RealtimePriority(5)
    priority.acquire()
    try:
        held = _policies()
        # every thread moved, but one that asked for the background before (a recorder's
        # writer an earlier test left), and those such a thread started
        asked_background = {tid for tid, policy in held.items() if policy in BACKGROUND_POLICIES}
        assert priority.held and {held[tid] for tid in held.keys() - asked_background} == {
            os.SCHED_FIFO
        }
        assert held[threading.get_native_id()] == held[thread.native_id] == os.SCHED_FIFO
        gone = {tid for tid in before if not os.path.exists(f"/proc/self/task/{tid}")}
        assert held.keys() >= before.keys() - gone  # every thread still there was looked at
        assert os.sched_getparam(0).sched_priority == 5
        late: list[int] = []
        later = threading.Thread(target=lambda: late.append(os.sched_getscheduler(0)))
        later.start()
        later.join()
        assert late == [os.SCHED_FIFO]  # threads started meanwhile inherit it
    finally:
        priority.release()
        stop.set()
        thread.join()
    after = _policies()
    assert {tid: after[tid] for tid in before if tid in after} == {
        tid: before[tid] for tid in before if tid in after
    }  # each thread back to the policy it had
    assert priority.summary() == {"realtime_priority": 5, "held": True}


@needs_root
def test_a_thread_started_while_the_threads_are_moved_is_moved_too(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A thread not moved yet starts one (under its own policy) between the look at the
    process's threads and the move: the next look moves it."""
    stop = threading.Event()
    started: list[threading.Thread] = []
    real_threads = rt_priority._threads

    def threads_starting_one() -> list[int]:
        seen = real_threads()
        if not started:  # the first look: a thread starts right after it
            started.append(threading.Thread(target=stop.wait, args=(5,), daemon=True))
            started[0].start()
        return seen

    monkeypatch.setattr(rt_priority, "_threads", threads_starting_one)
    priority = RealtimePriority(5)
    priority.acquire()
    try:
        assert os.sched_getscheduler(started[0].native_id) == os.SCHED_FIFO
    finally:
        priority.release()
        stop.set()
        started[0].join()


@needs_root
@pytest.mark.parametrize("clock", ["sim", "real"])
def test_the_servo_process_steps_under_sched_fifo_on_the_real_clock(
    clock: str, tmp_path: Path
) -> None:
    plan = check_text(GRAPH.format(clock=clock, priority=10), "rt.yaml", _registry())
    options = SchedulerOptions(clock=clock, duration=0.1, output_dir=tmp_path)
    before = _policies()
    result = Scheduler(plan, options).run().as_dict()
    (probe,) = (m for m in result["modules"] if m["module"] == "probe")
    if clock == "real":
        assert result["realtime_priority"] == {"realtime_priority": 10, "held": True}
        assert probe["policies"] == [os.SCHED_FIFO]
    else:
        assert result["realtime_priority"]["held"] is False
        assert result["realtime_priority"]["reason"].startswith("sim clock")
        assert probe["policies"] == [os.SCHED_OTHER]
    after = _policies()
    assert {t: after[t] for t in before if t in after} == {
        t: before[t] for t in before if t in after
    }


@needs_root
def test_a_host_that_refuses_runs_anyway_and_says_why() -> None:
    code = (
        "import json, os;"
        "from umbra.runtime.rt_priority import RealtimePriority;"
        "os.setuid(65534);"  # nobody: no CAP_SYS_NICE, no rtprio limit
        "p = RealtimePriority(10); p.acquire();"
        "print(json.dumps([p.summary(), os.sched_getscheduler(0)]))"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        cwd=Path(__file__).resolve().parents[2],
        timeout=60,
    )
    assert proc.returncode == 0, proc.stderr
    summary, policy = json.loads(proc.stdout)
    assert summary["held"] is False
    assert summary["reason"].startswith("cannot set SCHED_FIFO")
    assert policy == os.SCHED_OTHER  # nothing half-moved
    assert "realtime_priority 10 not held" in proc.stderr


def _writer_tid(recording: object) -> int:
    thread = recording._thread  # type: ignore[attr-defined]
    for _ in range(200):
        if thread.native_id is not None:
            return int(thread.native_id)
        threading.Event().wait(0.01)
    raise AssertionError("the recorder's thread did not start")


@needs_root
def test_a_recording_writer_follows_the_loop_into_sched_fifo_and_hands_the_gil_over_fast(
    tmp_path: Path,
) -> None:
    """The GIL priority inversion: a recording's writer under SCHED_BATCH was preempted while
    holding the GIL, and the servo loop waited for it (recording made the tick p99 30 ms late).
    Now the writer is only niced: in an ordinary process it stays in the default policy at
    nice 10, in a real-time one it runs under SCHED_FIFO beside the loop, and the loop gets the
    GIL within 0.5 ms; a video encoder (``background``) stays under SCHED_BATCH."""
    from umbra.runtime.recording.writer import WRITER_NICE, RecordingFile
    from umbra.runtime.rt_priority import GIL_SWITCH_S, background

    encoder_started, stop = threading.Event(), threading.Event()

    def encoder() -> None:
        background()
        encoder_started.set()
        stop.wait(10)

    video = threading.Thread(target=encoder, daemon=True)
    video.start()
    encoder_started.wait(5)
    switch_before = sys.getswitchinterval()
    ordinary = RecordingFile(tmp_path / "ordinary.mcap")
    try:
        tid = _writer_tid(ordinary)
        threading.Event().wait(0.2)  # the thread lowers itself as it starts
        assert os.sched_getscheduler(tid) == os.SCHED_OTHER
        assert os.getpriority(os.PRIO_PROCESS, tid) == WRITER_NICE
    finally:
        ordinary.close()
    priority = RealtimePriority(5)
    priority.acquire()
    try:
        assert sys.getswitchinterval() == pytest.approx(GIL_SWITCH_S)
        recording = RecordingFile(tmp_path / "servo.mcap")  # started by the loop's thread
        try:
            tid = _writer_tid(recording)
            threading.Event().wait(0.2)
            assert os.sched_getscheduler(tid) == os.SCHED_FIFO
            assert os.sched_getscheduler(int(video.native_id or 0)) == os.SCHED_BATCH
        finally:
            recording.close()
    finally:
        priority.release()
        stop.set()
        video.join(5)
    assert sys.getswitchinterval() == pytest.approx(switch_before)
