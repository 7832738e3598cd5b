"""The README's recipe across two "hosts" (network namespaces joined by a veth pair): mutual TLS
with the keys and rules of ``umbra keys``; the samples flow, and a peer on the producer's host
without a certificate, or with another CA's, cannot open a link to the consumer."""

from __future__ import annotations

import json
import signal
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from tests.links.conftest import Running, run_umbra, watched_counter_graph
from tests.links.test_two_hosts import Hosts, hosts  # noqa: F401  (the fixture)

pytestmark = [pytest.mark.netns, pytest.mark.slow]

ATTACKER = """
import json, sys, time, zenoh
cfg = zenoh.Config()
cfg.insert_json5("mode", '"peer"')
cfg.insert_json5("scouting/multicast/enabled", "false")
cfg.insert_json5("scouting/gossip/enabled", "false")
cfg.insert_json5("connect/endpoints", json.dumps([sys.argv[1]]))
tls = json.loads(sys.argv[2])
if tls:
    cfg.insert_json5("transport/link/tls", json.dumps(tls))
s = zenoh.open(cfg)
time.sleep(1.5)
print("peers", len(list(s.info.peers_zid())))
for i in range(20):
    s.put("umbra/tls2/counter/count", b"x" * 40)
s.close()
"""


def test_mtls_with_derived_rules_across_two_hosts(
    hosts: Hosts,  # noqa: F811
    umbra: Callable[..., Running],
    plugin_env: dict[str, str],
    tmp_path: Path,
) -> None:
    (tmp_path / "g.yaml").write_text(watched_counter_graph("tls2"))
    done = run_umbra(plugin_env, tmp_path, "keys", "g.yaml", "--out", "keys")
    assert done.returncode == 0, done.stderr
    done = run_umbra(plugin_env, tmp_path, "keys", "g.yaml", "--out", "other")
    assert done.returncode == 0, done.stderr
    endpoint = f"tls/{hosts.address_b}:7447"
    consumer = umbra(
        "run", "g.yaml", "--process", "smart", "--zenoh-config", "keys/", "--listen", endpoint,
        "--out", "out", "--duration", "60", prefix=("ip", "netns", "exec", hosts.b),
    )  # fmt: skip
    producer = umbra(
        "run", "g.yaml", "--process", "umbra", "--zenoh-config", "keys/", "--connect", endpoint,
        "--out", "out", "--duration", "60", prefix=("ip", "netns", "exec", hosts.a),
    )  # fmt: skip
    consumer.wait_for("link up", timeout=30)
    # peers on the producer's host: no certificate, then a certificate of another CA
    other = tmp_path / "other"
    refused = {
        "no certificate": {"root_ca_certificate": str(tmp_path / "keys" / "ca.pem")},
        "another CA": {
            "root_ca_certificate": str(other / "ca.pem"),
            "connect_private_key": str(other / "umbra.key"),
            "connect_certificate": str(other / "umbra.pem"),
            "enable_mtls": True,
            "verify_name_on_connect": False,
        },
    }
    for what, tls in refused.items():
        attack = run_umbra_python(hosts.a, plugin_env, tmp_path, endpoint, tls)
        assert "peers 0" in attack, f"{what}: {attack}"
    time.sleep(0.3)
    for run in (consumer, producer):
        run.popen.send_signal(signal.SIGINT)
    assert consumer.finish() == 130, consumer.text
    assert producer.finish() == 130, producer.text
    summary = json.loads((tmp_path / "out" / "summary-smart.json").read_text())
    (sub,) = summary["links"]["subscribe"]
    assert sub["received"] > 50 and sub["foreign"] == 0 and sub["decode_errors"] == 0


def run_umbra_python(
    namespace: str, env: dict[str, str], cwd: Path, endpoint: str, tls: dict[str, object]
) -> str:
    """Run the attacker script in ``namespace``; its output."""
    import subprocess
    import sys

    done = subprocess.run(
        ["ip", "netns", "exec", namespace, sys.executable, "-c", ATTACKER, endpoint,
         json.dumps(tls)],
        cwd=cwd, env=env, capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    return done.stdout + done.stderr
