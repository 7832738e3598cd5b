"""An insider of the graph cannot bend the time base: old data never passes the guard.

Real parts: processes `smart` (the guard and a simulated Puma) and `umbra` (the commands) started
by hand on loopback with real zenoh sessions; `umbra` runs in a Linux time namespace whose
``CLOCK_MONOTONIC`` is 0.3 s ahead of `smart`'s (``tests/links/timens.py``), as another host's
clock would be. Every command it sends is made from sensor data 0.45 s old, over REG_VEL's
0.25 s bound: none may pass, and the arm must not move.

The insider is a zenoh session with the credentials of the graph's own process `ui` (what a
compromised operator's process holds): it declares a queryable on `umbra`'s clock key that holds
every query until zenoh's timeout. Before clocks had owners, that widened the bound to 0.25 s, the
0.05 s left of the offset looked like nothing and was dropped with the bound, and every command
passed 0.3 s younger than it was (the arm moved). Now the graph's access rules let no process but
`umbra` answer for `umbra`'s clock (the insider is never asked), and without access rules
(``--insecure``) the true reply is taken as it comes whatever the impostor holds.
"""

from __future__ import annotations

import os
import sys
import threading
from pathlib import Path

import pytest
import zenoh

from tests.links.conftest import Running, guarded_arm_graph, start_umbra, stop_all
from tests.links.pickup import module, summary
from tests.links.probes import ArmWatch, LinkWatch, ProbeTwist
from tests.links.test_attacks import _realtime
from umbra.modules.generic.counter import Counter
from umbra.runtime.graph.check import check_spec
from umbra.runtime.graph.parse import parse_graph_text
from umbra.runtime.links.clock_sync import CLOCK
from umbra.runtime.links.config import Endpoints, build_config, free_loopback_ports
from umbra.runtime.links.host_auth import host_credentials, secret_folder
from umbra.runtime.links.session import wait_joined
from umbra.runtime.registry import Registry

pytestmark = pytest.mark.slow

#: How far `umbra`'s monotonic clock is ahead of `smart`'s [s], and how old its data is [s].
AHEAD_S = 0.3
LAG_S = 0.45
TIMENS = Path(__file__).with_name("timens.py")


def _graph() -> str:
    graph = guarded_arm_graph("clockattack", extra_process=True)
    source = "  source: {type: ProbeTwist, process: umbra, rate: 50}\n"
    aged = (
        "  source: {type: ProbeTwist, process: umbra, rate: 50,\n"
        f"           params: {{vx: 0.02, origin_lag: {LAG_S}}}}}\n"
    )
    assert source in graph
    return graph.replace(source, aged)


def _credentials(text: str, process: str, env: dict[str, str]) -> dict[str, object]:
    """``process``'s credentials as the graph's processes started by hand derive them (from the
    user's secret, as an insider on this host can)."""
    registry = Registry()
    for cls in (ProbeTwist, ArmWatch, Counter, LinkWatch):
        registry.add(cls)
    plan = check_spec(parse_graph_text(text, "g.yaml"), registry)
    return host_credentials(plan, process, secret_folder(env))


@pytest.mark.parametrize("access", ["credentials", "insecure"])
def test_an_insider_holding_clock_queries_lets_no_old_command_pass(
    plugin_env: dict[str, str], tmp_path: Path, access: str
) -> None:
    if not _time_namespace_ok():
        pytest.skip("needs root for a time namespace (unshare CLONE_NEWTIME)")
    text = _graph()
    (tmp_path / "g.yaml").write_text(text)
    insecure = ("--insecure",) if access == "insecure" else ()
    p_smart, p_umbra = free_loopback_ports(2)
    smart_ep, umbra_ep = f"tcp/127.0.0.1:{p_smart}", f"tcp/127.0.0.1:{p_umbra}"
    common = ("--out", "out", "--duration", "8", *insecure)
    runs: list[Running] = []
    held: list[zenoh.Query] = []
    asked = threading.Event()

    def withhold(query: zenoh.Query) -> None:
        asked.set()
        held.append(query)  # never answered: zenoh waits for it until the query times out

    insider: zenoh.Session | None = None
    try:
        consumer = start_umbra(
            plugin_env, tmp_path, "run", "g.yaml", "--process", "smart", "--listen", smart_ep,
            *common, prefix=_realtime(),
        )  # fmt: skip
        runs.append(consumer)
        auth = None if insecure else _credentials(text, "ui", plugin_env)
        insider = zenoh.open(build_config(Endpoints(connect=[smart_ep]), auth=auth))  # type: ignore[arg-type]
        assert wait_joined(insider, 1, 20.0) == 1, "the insider is let in as `ui`"
        insider.declare_queryable(f"umbra/clockattack/{CLOCK}/umbra/**", withhold)
        producer = start_umbra(
            plugin_env, tmp_path, "run", "g.yaml", "--process", "umbra", "--connect", smart_ep,
            "--listen", umbra_ep, *common,
            prefix=(sys.executable, str(TIMENS), str(AHEAD_S)),
        )  # fmt: skip
        runs.append(producer)
        consumer.wait_for("process `umbra` is up")
        assert consumer.finish(timeout=60) == 0, consumer.text
        producer.finish(timeout=30)
    finally:
        if insider is not None:
            held.clear()
            insider.close()
        stop_all(runs)
    smart = summary(tmp_path / "out", "smart")
    clock = smart["links"]["clocks"]["umbra"]
    assert not clock["same_clock"], clock
    assert clock["error_ms"] < 20.0, clock  # the loopback round trip, not the held 500 ms
    assert abs(clock["offset_ms"] - AHEAD_S * 1e3) <= clock["error_ms"] + 2.0, clock
    if access == "credentials":
        assert not asked.is_set(), "the graph's access rules let `ui` answer for `umbra`'s clock"
    else:
        assert asked.is_set(), "without access rules the impostor is asked (and not waited for)"
    register = module(smart, "register")
    assert register["passed_origin_age_ms"]["ticks"] == 0, register  # nothing old passed
    assert register["stale_zero_ticks"] > 200, register
    refused = register["refused_origin_age_ms"]
    assert refused["p50"] >= (LAG_S - 0.02) * 1e3, refused  # judged as old as it is
    assert module(smart, "arm")["moved_rad"] < 1e-9


def _time_namespace_ok() -> bool:
    return os.geteuid() == 0 and Path("/proc/self/timens_offsets").exists()
