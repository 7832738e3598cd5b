"""The README's recipe across two "hosts" (network namespaces joined by a veth pair): the split
pick-up over mutual TLS with the keys and the access rules ``umbra keys`` derives from the graph.

Vision (`umbra`) runs on one host and connects to the servo side (`smart`), which listens on
the other host's address. Before the simulated operator clicks (the arm holds still until then),
three peers on the vision host try to command the arm: one with no certificate, one with a
certificate of another CA, and one with the valid certificate of the wrong process of the graph
(`smart`'s, posing as `umbra`). The first two cannot open a link; the third is let in but zenoh's
rules drop what it publishes before any link sees it. The arm does not move until the attacks are
over, and the pick-up grasps.
"""

from __future__ import annotations

import json
import math
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from tests.links.conftest import Running, run_umbra
from tests.links.pickup import TWIST_KEY, link, module, pickup_with_watch, summary
from tests.links.test_two_hosts import Hosts, hosts  # noqa: F401  (the fixture)

pytestmark = [pytest.mark.netns, pytest.mark.slow]

#: Seconds the simulated operator waits before clicking: the attacks happen before.
CLICK_DELAY = 25.0

ATTACKER = """
import json, sys, time, zenoh
import numpy as np
from umbra.connectors.codec import Codec
from umbra.connectors.messages import Twist
endpoint, tls, key, alive = sys.argv[1], json.loads(sys.argv[2]), sys.argv[3], sys.argv[4]
cfg = zenoh.Config()
cfg.insert_json5("mode", '"peer"')
cfg.insert_json5("scouting/multicast/enabled", "false")
cfg.insert_json5("scouting/gossip/enabled", "false")
cfg.insert_json5("connect/endpoints", json.dumps([endpoint]))
cfg.insert_json5("transport/link/tls", json.dumps(tls))
s = zenoh.open(cfg)
deadline = time.monotonic() + 3.0
while time.monotonic() < deadline and not list(s.info.peers_zid()):
    time.sleep(0.05)
time.sleep(0.5)
print("peers", len(list(s.info.peers_zid())), flush=True)
token = s.liveliness().declare_token(f"{alive}/umbra/none/{s.zid()}/none")
codec = Codec()
for i in range(50):
    twist = Twist(vector=np.array([0.05, 0, 0, 0, 0, 0.0]), frame="camera", seq=1 + i)
    s.put(key, codec.encode(twist))
    time.sleep(0.01)
token.undeclare()
s.close()
"""


def attack(namespace: str, env: dict[str, str], cwd: Path, endpoint: str, tls: dict) -> str:
    """Run the attacker in ``namespace`` (the vision host); its output."""
    done = subprocess.run(
        ["ip", "netns", "exec", namespace, sys.executable, "-c", ATTACKER, endpoint,
         json.dumps(tls), TWIST_KEY, "umbra/tool_pickup/_alive"],
        cwd=cwd, env=env, capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    return done.stdout + done.stderr


def test_mtls_pick_up_across_two_hosts_refuses_every_other_peer(
    hosts: Hosts,  # noqa: F811
    umbra: Callable[..., Running],
    plugin_env: dict[str, str],
    tmp_path: Path,
) -> None:
    graph = pickup_with_watch(tmp_path)  # the page beside vision: two hosts, two processes
    for folder in ("keys", "other"):
        done = run_umbra(
            plugin_env,
            tmp_path,
            "keys",
            graph,
            "--out",
            folder,
            "--host",
            f"smart={hosts.address_b}",
        )
        assert done.returncode == 0, done.stderr
    keys, other = tmp_path / "keys", tmp_path / "other"
    endpoint = f"tls/{hosts.address_b}:7447"
    common = ("--zenoh-config", "keys/", "--out", "out", "--set",
              f"operator.click_delay_s={CLICK_DELAY}")  # fmt: skip
    smart = umbra(
        "run", graph, "--process", "smart", "--listen", "tls/0.0.0.0:7447", *common,
        prefix=("ip", "netns", "exec", hosts.b),
    )  # fmt: skip
    vision = umbra(
        "run", graph, "--process", "umbra", "--connect", endpoint, *common,
        prefix=("ip", "netns", "exec", hosts.a),
    )  # fmt: skip
    smart.wait_for("links ready", timeout=60)
    vision.wait_for("links ready", timeout=60)
    attack_start = time.monotonic()

    def certificate(of: Path, process: str) -> dict[str, object]:
        return {
            "root_ca_certificate": str(of / "ca.pem"),
            "connect_private_key": str(of / f"{process}.key"),
            "connect_certificate": str(of / f"{process}.pem"),
            "enable_mtls": True,
            "verify_name_on_connect": False,
        }

    attacks = {
        "no certificate": {"root_ca_certificate": str(keys / "ca.pem")},
        "another CA": certificate(other, "umbra"),  # the producer's name, the wrong CA
        "the wrong process": certificate(keys, "smart"),  # valid, but not the producer's
    }
    said = {
        what: attack(hosts.a, plugin_env, tmp_path, endpoint, tls) for what, tls in attacks.items()
    }
    attack_end = time.monotonic()
    assert "peers 0" in said["no certificate"], said
    assert "peers 0" in said["another CA"], said
    assert "peers 1" in said["the wrong process"], said  # let in: it is a process of the graph
    assert "Traceback" not in "".join(said.values()), said
    assert vision.wait_for("stage approach", timeout=CLICK_DELAY + 30)  # still acquiring before
    assert smart.finish(timeout=120) == 0, smart.text
    vision.popen.send_signal(signal.SIGINT)
    vision.finish()
    assert "grasped" in smart.wait_for("umbra.world: grasped")
    smart_summary = summary(tmp_path / "out", "smart")
    twist = link(smart_summary, TWIST_KEY)
    # nothing of the attackers reached a link: zenoh refused the sessions, and the rules
    # dropped the insider's samples and its token before the transport saw them
    assert twist["foreign"] == 0 and twist["unattributed"] == 0, twist
    assert twist["received"] > 100 and twist["decode_errors"] == 0, twist
    assert smart_summary["links"]["token_conflicts"] == 0
    arm = module(smart_summary, "arm")
    assert not math.isnan(arm["first_moved_at"]) and arm["first_moved_at"] > attack_end, arm
    assert attack_start < attack_end
