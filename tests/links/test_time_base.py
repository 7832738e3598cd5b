"""One time base across processes: origins from a producer whose clock differs are put on the
consumer's clock, within the bound the summary reports.

Real parts: two ``umbra run --process`` started by hand on loopback, with real zenoh sessions and
the per-user credentials; the producer runs in a Linux time namespace whose CLOCK_MONOTONIC is
ahead by ``SKEW_S`` (``unshare --time --monotonic``: root only, skipped otherwise), as the clock of
another host would be. Without the offset the consumer would judge every command 5 s in the
future (or, the other way round, 5 s old and refuse them all).
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
from pathlib import Path

import pytest

from tests.links.conftest import start_umbra, stop_all
from umbra.runtime.links.config import free_loopback_ports

#: How far the producer's monotonic clock is ahead of the consumer's [s] (whole seconds).
SKEW_S = 5

GRAPH = """
graph: timebase
clock: real
processes: {umbra: {}, smart: {}}
modules:
  source:                 # a constant twist, dated by its own stamp (it reads no sensor)
    type: TwistSource
    process: umbra
    rate: 50
    params: {twist: [0.01, 0, 0, 0, 0, 0], frame: camera}
  register:
    type: REG_VEL
    process: smart
    rate: 100
    params: {timeout: 0.1, max_origin_age: 0.1}
connections:
  - source.twist -> register.command
"""


def _time_namespaces() -> str:
    if os.geteuid() != 0 or shutil.which("unshare") is None:
        return "needs root and unshare(1) for a time namespace"
    probe = subprocess.run(
        ["unshare", "--time", "--monotonic", "1", "--fork", "true"], capture_output=True
    )
    return "" if probe.returncode == 0 else f"no time namespaces here: {probe.stderr!r}"


@pytest.mark.slow
@pytest.mark.skipif(bool(_time_namespaces()), reason=_time_namespaces() or "ok")
def test_a_producer_on_another_clock_is_dated_on_ours(
    plugin_env: dict[str, str], tmp_path: Path
) -> None:
    (tmp_path / "g.yaml").write_text(GRAPH)
    (port,) = free_loopback_ports(1)
    endpoint = f"tcp/127.0.0.1:{port}"
    common = ("--out", "out", "--duration", "4")
    runs = []
    try:
        consumer = start_umbra(
            plugin_env, tmp_path, "run", "g.yaml", "--process", "smart", "--listen", endpoint,
            *common,
        )  # fmt: skip
        runs.append(consumer)
        producer = start_umbra(
            plugin_env, tmp_path, "run", "g.yaml", "--process", "umbra", "--connect", endpoint,
            *common,
            prefix=("unshare", "--time", "--monotonic", str(SKEW_S), "--fork"),
        )  # fmt: skip
        runs.append(producer)
        try:
            consumer.wait_for("process `umbra` is up")
        except AssertionError as exc:
            raise AssertionError(f"{exc}\nproducer:\n{producer.text}") from None
        assert consumer.finish(timeout=60) == 0, consumer.text
        producer.popen.send_signal(signal.SIGINT)
        producer.finish(timeout=30)
    finally:
        stop_all(runs)
    summary = json.loads((tmp_path / "out" / "summary-smart.json").read_text())
    clock = summary["links"]["clocks"]["umbra"]
    assert clock["offset_ms"] == pytest.approx(SKEW_S * 1e3, abs=clock["error_ms"] + 1.0)
    assert clock["error_ms"] < 5.0  # half the best round trip over loopback
    assert not clock["same_clock"]
    (register,) = [m for m in summary["modules"] if m["module"] == "register"]
    ages = register["passed_origin_age_ms"]
    # commands passed, dated on our clock: fresh (a 50 Hz source: at most 20 ms plus the link),
    # never "5 s in the future" (negative) nor refused as 5 s old
    assert ages["ticks"] > 200, register
    assert 0.0 <= ages["p50"] <= 60.0, register
    assert register["stale_zero_ticks"] < 20, register  # at most the first, undatable samples
