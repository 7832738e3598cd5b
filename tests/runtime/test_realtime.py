"""Holding the CPU wake-up latency: the PM QoS request, the graph setting, the run summary."""

from __future__ import annotations

import logging
import os
import struct
from pathlib import Path

import pytest

from tests.runtime.fixtures import make_registry
from umbra.runtime.graph.check import check_text
from umbra.runtime.realtime import (
    NO_CONSTRAINT_US,
    PM_QOS_FILE,
    CpuLatencyHold,
    current_cpu_latency_us,
    latency_limit,
)
from umbra.runtime.scheduler import Scheduler, SchedulerOptions

KERNEL_QOS = os.access(PM_QOS_FILE, os.R_OK | os.W_OK)


def _open_on(path: Path) -> bool:
    """Whether this process holds a file descriptor on ``path``."""
    fds = Path("/proc/self/fd")
    return any(os.path.realpath(fd) == str(path.resolve()) for fd in fds.iterdir())


def test_the_limit_is_written_as_a_32_bit_integer_and_the_file_kept_open(tmp_path: Path) -> None:
    qos = tmp_path / "qos"
    qos.write_bytes(b"")
    with CpuLatencyHold(25, path=qos) as hold:
        assert hold.held and _open_on(qos)
        assert hold.summary() == {"cpu_latency_us": 25, "held": True}
    assert qos.read_bytes() == struct.pack("=i", 25)
    assert not _open_on(qos)  # closing the file is what ends the kernel's request


def test_a_host_that_refuses_is_reported_and_the_run_goes_on(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    qos = tmp_path / "absent" / "qos"
    with caplog.at_level(logging.WARNING), CpuLatencyHold(0, path=qos) as hold:
        assert not hold.held
    assert hold.summary()["reason"].startswith(f"cannot open {qos}")
    (line,) = [r.getMessage() for r in caplog.records]
    assert "cpu_latency_us 0 not held" in line and "needs root" in line


def test_no_limit_asks_nothing(tmp_path: Path) -> None:
    qos = tmp_path / "qos"
    with CpuLatencyHold(None, path=qos) as hold:
        assert not hold.held and not qos.exists()


@pytest.mark.skipif(not KERNEL_QOS, reason=f"{PM_QOS_FILE} needs root (read and write)")
def test_the_kernel_enforces_the_request_only_while_it_is_held() -> None:
    with CpuLatencyHold(0):
        assert current_cpu_latency_us() == 0
        assert _holding_qos()
    assert not _holding_qos()


def _holding_qos() -> bool:
    """Whether this process holds a request open (another process, a test beside this one on
    another worker, may hold one of its own: the kernel's figure is the smallest of them)."""
    fds = Path("/proc/self/fd")
    return any(
        os.path.realpath(fds / fd) == str(PM_QOS_FILE) for fd in os.listdir(fds) if fd.isdigit()
    )


def test_which_limit_a_process_holds() -> None:
    asked = {"smart": 0, "umbra": 500}
    assert latency_limit(asked, "smart") == 0
    assert latency_limit(asked, "umbra") == 500
    assert latency_limit(asked, "other") is None
    assert latency_limit(asked, None) == 0  # one process for all: the strictest request
    assert latency_limit({}, None) is None
    assert latency_limit(asked, "umbra", override=50) == 50


GRAPH = """graph: rt
clock: {clock}
processes:
  umbra: {{}}
  smart: {{cpu_latency_us: 0}}
modules:
  src: {{type: Counter, process: umbra, rate: 100}}
  g: {{type: Gain, process: smart, params: {{gain: 2}}}}
connections:
  - src.count -> g.input
"""


def test_the_graph_asks_per_process() -> None:
    plan = check_text(GRAPH.format(clock="sim"), "rt.yaml", make_registry())
    assert plan.spec.cpu_latency_us == {"smart": 0}
    assert NO_CONSTRAINT_US == 2_000_000_000


@pytest.mark.parametrize("clock", ["sim", "real"])
def test_the_run_summary_says_whether_the_latency_was_held(clock: str, tmp_path: Path) -> None:
    plan = check_text(GRAPH.format(clock=clock), "rt.yaml", make_registry())
    limit = latency_limit(plan.spec.cpu_latency_us, None)
    options = SchedulerOptions(
        clock=clock, duration=0.05, output_dir=tmp_path, cpu_latency_us=limit
    )
    result = Scheduler(plan, options).run()
    realtime = result.as_dict()["realtime"]
    assert realtime["cpu_latency_us"] == 0
    if clock == "sim":
        assert realtime == {
            "cpu_latency_us": 0,
            "held": False,
            "reason": "sim clock: nothing waits for a CPU to wake",
        }
    else:
        assert realtime["held"] is KERNEL_QOS
    if KERNEL_QOS:
        assert not _holding_qos()  # released when the run ended


def test_check_shows_the_latency_each_process_holds(tmp_path: Path, capsys) -> None:
    from umbra.runtime.cli.main import main

    path = tmp_path / "rt.yaml"
    path.write_text(GRAPH.format(clock="real"))
    assert main(["check", str(path)]) == 0
    assert "processes: umbra, smart (cpu_latency_us 0)" in capsys.readouterr().out


def test_a_run_on_a_host_that_refuses_goes_on_and_its_summary_says_why(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import functools

    import umbra.runtime.process_holds

    absent = tmp_path / "absent" / "qos"
    monkeypatch.setattr(
        umbra.runtime.process_holds,
        "CpuLatencyHold",
        functools.partial(CpuLatencyHold, path=absent),
    )
    plan = check_text(GRAPH.format(clock="real"), "rt.yaml", make_registry())
    options = SchedulerOptions(clock="real", duration=0.05, output_dir=tmp_path, cpu_latency_us=0)
    result = Scheduler(plan, options).run()
    assert result.exit_code == 0 and result.ticks > 0
    realtime = result.as_dict()["realtime"]
    assert realtime["held"] is False
    assert realtime["reason"].startswith(f"cannot open {absent}")
