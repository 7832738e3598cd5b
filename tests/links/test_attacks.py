"""Attacks on the servo path of a split graph (real processes, real zenoh on loopback).

The genuine command is a zero twist: whatever moves the simulated Puma came from an attacker.
Each scene checks that the arm never moved, that the servo side's ticks kept their period (the
longest gap between two 100 Hz ticks while under attack stays under twice the period) and that
the run went on. The servo side runs with a real-time scheduling policy (``chrt -f``), as on a
robot's computer: on this shared test machine an ordinary process misses 20-50 ms now and then
with no attack at all; with the policy, none in steady state.

* By hand with ``--insecure`` (``--process`` on loopback without credentials: the weakest setup,
  where only the links' own checks stand): a foreign peer commanding as itself, a
  sequence-number jam and floods of 64 MB and 512 kB samples carrying a copied source id, then a
  replay after the producer is killed.
* By hand as started by default (credentials derived from the user's secret): a peer without
  them, as itself or claiming the producer's zenoh id, cannot open a session with either
  process.
* Under the launcher (per-run credentials and the graph's access rules): a peer without
  credentials cannot open a session; an insider with the credentials of another process of the
  graph connects but can neither command the arm nor pose as the producer.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import time
from pathlib import Path

import numpy as np
import pytest
import zenoh

from tests.links.conftest import Running, guarded_arm_graph, start_umbra, stop_all
from tests.poll import wait_for
from umbra.connectors.codec import Codec
from umbra.connectors.messages import Twist
from umbra.runtime.links.config import Endpoints, build_config, free_loopback_ports
from umbra.runtime.links.identity import alive_key

pytestmark = pytest.mark.slow

#: Servo period of the graph [s] (REG_VEL, WOLVERINE_JNTS and ArmWatch run at 100 Hz).
PERIOD = 0.01
FOREIGN = Twist(vector=np.array([0.05, 0, 0, 0, 0, 0.0]), frame="camera", seq=1)


def _realtime() -> tuple[str, ...]:
    """The prefix running a command with a real-time policy; skips without one."""
    if shutil.which("chrt") is None or os.geteuid() != 0:
        pytest.skip("the servo side needs a real-time policy (chrt -f, as root) for its tick gap")
    return ("chrt", "-f", "20")


def _start_by_hand(
    env: dict[str, str],
    tmp_path: Path,
    runs: list[Running],
    extra: tuple[str, ...],
    producer_prefix: tuple[str, ...] = (),
) -> tuple[Running, Running, str, str]:
    """Processes `smart` (real-time policy, listening) and `umbra` (connecting to it) of
    ``g.yaml`` started by hand, each added to ``runs``; returns them and their endpoints once
    the guard passes the producer's commands."""
    p_smart, p_umbra = free_loopback_ports(2)
    smart_ep, umbra_ep = f"tcp/127.0.0.1:{p_smart}", f"tcp/127.0.0.1:{p_umbra}"
    common = ("--out", "out", "--duration", "60", *extra)
    consumer = start_umbra(
        env, tmp_path, "run", "g.yaml", "--process", "smart", "--listen", smart_ep, *common,
        prefix=_realtime(),
    )  # fmt: skip
    runs.append(consumer)
    producer = start_umbra(
        env, tmp_path, "run", "g.yaml", "--process", "umbra", "--connect", smart_ep,
        "--listen", umbra_ep, *common, prefix=producer_prefix,
    )  # fmt: skip
    runs.append(producer)
    consumer.wait_for("guard passing")
    return consumer, producer, smart_ep, umbra_ep


def _gaps_within(arm: dict, start: float, end: float) -> float:
    """The longest gap between two servo ticks [s] that ended within ``[start, end]``."""
    return max((gap for at, gap in arm["long_gaps"] if start <= at <= end), default=0.0)


def _summary(folder: Path, process: str) -> dict:
    return json.loads((folder / f"summary-{process}.json").read_text())


def _module(summary: dict, name: str) -> dict:
    return next(m for m in summary["modules"] if m["module"] == name)


def test_by_hand_noise_attacks_and_replay_after_kill(
    plugin_env: dict[str, str], tmp_path: Path
) -> None:
    (tmp_path / "g.yaml").write_text(guarded_arm_graph("attack"))
    key = "umbra/attack/source/twist"
    runs: list[Running] = []
    codec = Codec()
    try:
        consumer, producer, smart_ep, umbra_ep = _start_by_hand(
            plugin_env, tmp_path, runs, ("--insecure",)
        )
        attacker = zenoh.open(build_config(Endpoints(connect=[smart_ep, umbra_ep])))
        try:
            overheard: list[zenoh.Sample] = []
            spy = attacker.declare_subscriber(key, overheard.append)
            pub = attacker.declare_publisher(key, congestion_control=zenoh.CongestionControl.BLOCK)
            wait_for(lambda: len(overheard) >= 20, 10.0, "20 overheard samples")
            source = overheard[-1].source_info
            attack_start = time.monotonic()
            # 1. a foreign peer commanding as itself, 50 Hz for half a second
            for _ in range(25):
                pub.put(codec.encode(FOREIGN), source_info=None)
                time.sleep(0.02)
            # 2. one sample with an absurd sequence number, in the producer's name
            jam = Twist(vector=np.zeros(6), frame="camera", seq=2**62)
            pub.put(codec.encode(jam), source_info=source)
            # 3. 64 MB samples (dropped by zenoh as it reassembles them: the process accepts
            # no message larger than its links need) and 512 kB ones (dropped by the link,
            # before decoding: a Twist's bound is 1 kB), in the producer's name
            for size in (64 << 20, 512 << 10) * 3:
                pub.put(b"\x00" * size, source_info=source)
            time.sleep(0.5)  # the genuine commands keep flowing after the noise
            # 4. the producer is killed; its recorded samples and new commands are replayed
            replay = [s.payload.to_bytes() for s in overheard[-20:]]
            spy.undeclare()
            killed_at = time.monotonic()
            os.kill(producer.popen.pid, signal.SIGKILL)
            consumer.wait_for("process `umbra` is gone", timeout=5)
            for i in range(25):
                pub.put(replay[i % len(replay)], source_info=source)
                later = Twist(vector=FOREIGN.vector, frame="camera", seq=10**6 + i)
                pub.put(codec.encode(later), source_info=source)
                time.sleep(0.02)
            time.sleep(0.2)  # a window: the replays are judged, none goes through
            attack_end = time.monotonic()
        finally:
            attacker.close()
        consumer.popen.send_signal(signal.SIGINT)
        assert consumer.finish() == 130, consumer.text
    finally:
        stop_all(runs)
    summary = _summary(tmp_path / "out", "smart")
    arm = _module(summary, "arm")
    assert arm["moved_rad"] < 1e-9  # the arm never followed a foreign command
    assert _gaps_within(arm, attack_start, attack_end) < 2 * PERIOD, arm["long_gaps"]
    # the guard held through the noise and zeroed once, when the producer was killed
    assert [t for t in arm["zeroed_at"] if t >= attack_start] == [
        t for t in arm["zeroed_at"] if t >= killed_at
    ]
    assert len([t for t in arm["zeroed_at"] if t >= killed_at]) == 1, arm
    (sub,) = summary["links"]["subscribe"]
    assert sub["foreign"] == 25
    assert sub["implausible"] == 1 and sub["oversize"] == 3
    assert sub["after_gone"] >= 50 - 5  # a few may race the liveliness news
    assert sub["decode_errors"] == 0 and sub["stale_dropped"] <= 5


def test_by_hand_with_derived_credentials_a_peer_without_them_cannot_connect(
    plugin_env: dict[str, str], tmp_path: Path
) -> None:
    """The producer runs with a real-time policy below the servo side's: on this shared machine a
    producer stalled for 0.1 s would let REG_VEL's watchdog zero the arm, which is no part of
    what is tested here."""
    (tmp_path / "g.yaml").write_text(guarded_arm_graph("byhand_auth"))
    key = "umbra/byhand_auth/source/twist"
    runs: list[Running] = []
    codec = Codec()
    try:
        consumer, _producer, smart_ep, umbra_ep = _start_by_hand(
            plugin_env, tmp_path, runs, (), producer_prefix=("chrt", "-f", "10")
        )
        up = consumer.wait_for("process `umbra` is up")
        producer_zid = re.search(r"session ([0-9a-f]+)", up).group(1)  # type: ignore[union-attr]
        attack_start = time.monotonic()
        for zid in (None, producer_zid):  # as itself, then in the producer's name
            cfg = build_config(Endpoints(connect=[smart_ep, umbra_ep]))
            if zid is not None:
                cfg.insert_json5("id", json.dumps(zid))
            attacker = zenoh.open(cfg)
            try:
                overheard: list[zenoh.Sample] = []
                spy = attacker.declare_subscriber(key, overheard.append)
                pub = attacker.declare_publisher(
                    key, congestion_control=zenoh.CongestionControl.BLOCK
                )
                time.sleep(1.0)  # a window: the handshakes are refused
                assert list(attacker.info.peers_zid()) == []  # refused by both processes
                spy.undeclare()
                assert overheard == []  # 100 genuine commands went by, none to it
                for i in range(25):
                    msg = Twist(vector=FOREIGN.vector, frame="camera", seq=10**5 + i)
                    pub.put(codec.encode(msg), source_info=zenoh.SourceInfo(pub.id, i))
                    time.sleep(0.02)
            finally:
                attacker.close()
        attack_end = time.monotonic()
        consumer.popen.send_signal(signal.SIGINT)
        assert consumer.finish() == 130, consumer.text
    finally:
        stop_all(runs)
    summary = _summary(tmp_path / "out", "smart")
    arm = _module(summary, "arm")
    assert arm["moved_rad"] < 1e-9, arm
    register = _module(summary, "register")
    assert not [t for t in arm["zeroed_at"] if attack_start <= t <= attack_end], register
    assert _gaps_within(arm, attack_start, attack_end) < 2 * PERIOD, arm["long_gaps"]
    (sub,) = summary["links"]["subscribe"]
    assert sub["received"] > 200  # the genuine commands kept flowing
    for counter in ("foreign", "implausible", "oversize", "decode_errors", "after_gone"):
        assert sub[counter] == 0, (counter, sub)  # stopped by zenoh, before the link's checks
    assert summary["links"]["token_conflicts"] == 0 and summary["links"]["forged_tokens"] == 0


def _auth_folder(launcher: Running) -> Path:
    """The launcher's per-run credentials folder (an insider on this host can read it as root)."""
    started = [line for line in launcher.stderr if "started process" in line]
    pid = int(re.search(r"pid (\d+)", started[0]).group(1))  # type: ignore[union-attr]
    cmdline = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
    return Path(cmdline[cmdline.index(b"--link-auth") + 1].decode()).parent


def test_under_the_launcher_strangers_cannot_connect_and_insiders_cannot_command(
    plugin_env: dict[str, str], tmp_path: Path
) -> None:
    _realtime()  # root and a real-time policy, or skip
    # the servo process alone under SCHED_FIFO, as the shipped graphs ask: the other processes
    # (the launcher's, starting as the attack begins) cannot hold its loop back
    graph = guarded_arm_graph("insider", extra_process=True, realtime_priority=20)
    (tmp_path / "g.yaml").write_text(graph)
    key = "umbra/insider/source/twist"
    launcher = start_umbra(plugin_env, tmp_path, "run", "g.yaml", "--out", "out", "--duration", "5")
    codec = Codec()
    try:
        launcher.wait_for("guard passing")
        endpoints = re.findall(r"listening on (tcp/127\.0\.0\.1:\d+)", launcher.text)
        assert len(endpoints) == 3
        folder = _auth_folder(launcher)
        assert folder.stat().st_mode & 0o077 == 0
        attack_start = time.monotonic()
        # a stranger: no credentials
        stranger = zenoh.open(build_config(Endpoints(connect=endpoints)))
        try:
            time.sleep(1.0)  # a window: the handshakes are refused
            assert list(stranger.info.peers_zid()) == []  # refused by every process
        finally:
            stranger.close()
        # an insider: the credentials of process `ui`, which has no business commanding
        ui = json.loads((folder / "ui.json").read_text())
        insider_cfg = build_config(Endpoints(connect=endpoints))
        usrpwd = {k: ui[k] for k in ("user", "password")}
        insider_cfg.insert_json5("transport/auth/usrpwd", json.dumps(usrpwd))
        insider = zenoh.open(insider_cfg)
        try:
            # it is let in
            wait_for(lambda: len(list(insider.info.peers_zid())) == 3, 10.0, "the insider let in")
            token = insider.liveliness().declare_token(
                alive_key("umbra/insider", "umbra", "none", str(insider.zid()))
            )
            pub = insider.declare_publisher(key, congestion_control=zenoh.CongestionControl.BLOCK)
            for i in range(50):
                msg = Twist(vector=FOREIGN.vector, frame="camera", seq=10**5 + i)
                pub.put(codec.encode(msg))
                time.sleep(0.02)
            token.undeclare()
        finally:
            insider.close()
        attack_end = time.monotonic()
        assert launcher.finish() == 0, launcher.text
    finally:
        stop_all([launcher])
    assert not folder.exists()  # the run's credentials are gone with it
    summary = _summary(tmp_path / "out", "smart")
    arm = _module(summary, "arm")
    assert arm["moved_rad"] < 1e-9, arm
    assert not [t for t in arm["zeroed_at"] if attack_start <= t <= attack_end], arm
    assert _gaps_within(arm, attack_start, attack_end) < 2 * PERIOD, arm["long_gaps"]
    assert summary["links"]["token_conflicts"] == 0  # the posing token never arrived
    twist = next(s for s in summary["links"]["subscribe"] if s["key"] == key)
    assert twist["foreign"] == 0 and twist["received"] > 100  # stopped by zenoh, before us
    ticks = _module(summary, "ticks")
    assert ticks["last_seq"] > 20  # the insider's own process still works
