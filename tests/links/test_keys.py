"""``umbra keys``: a CA, a certificate per process and the graph's access rules, used for real.

Three processes of one graph on loopback with mutual TLS (``tls/`` endpoints) and the derived
rules: the genuine samples flow; a peer with no certificate, a certificate of another CA (even
with the right common name) or a valid certificate of the wrong process of the graph cannot
put a sample on the producer's key, nor pose as the producer.
"""

from __future__ import annotations

import json
import stat
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
import zenoh

from tests.links.conftest import REPO
from tests.poll import wait_for
from umbra.connectors.codec import Codec
from umbra.connectors.errors import UserError
from umbra.connectors.messages import Message, Scalar
from umbra.runtime.cli.main import main as umbra_main
from umbra.runtime.graph.check import load_graph
from umbra.runtime.graph.plan import GraphPlan
from umbra.runtime.links.acl import common_name
from umbra.runtime.links.config import Endpoints, build_config, free_loopback_ports
from umbra.runtime.links.exposure import check_exposure, config_for
from umbra.runtime.links.identity import alive_key
from umbra.runtime.links.tls import write_keys
from umbra.runtime.links.transport import ZenohTransport

TRIO = """
graph: trio
processes: {umbra: {}, smart: {}, ui: {}}
modules:
  counter: {type: Counter, process: umbra, rate: 100}
  double: {type: Gain, process: smart}
  tick: {type: Counter, process: ui, rate: 10}
  show: {type: Gain, process: smart}
connections:
  - counter.count -> double.input
  - tick.count -> show.input
"""
KEY = "umbra/trio/counter/count"


@pytest.fixture(scope="module")
def trio(tmp_path_factory: pytest.TempPathFactory) -> tuple[GraphPlan, Path, Path]:
    """The graph, its keys, and the keys another CA made for the same graph."""
    folder = tmp_path_factory.mktemp("trio")
    (folder / "trio.yaml").write_text(TRIO)
    plan = load_graph(str(folder / "trio.yaml"))
    write_keys(plan, folder / "keys")
    write_keys(plan, folder / "other-ca")
    return plan, folder / "keys", folder / "other-ca"


def test_keys_are_private_and_rules_follow_the_graph(trio: tuple[GraphPlan, Path, Path]) -> None:
    _plan, keys, _other = trio
    assert stat.S_IMODE(keys.stat().st_mode) == 0o700
    for process in ("umbra", "smart", "ui"):
        assert stat.S_IMODE((keys / f"{process}.key").stat().st_mode) == 0o600
        assert stat.S_IMODE((keys / f"{process}.json5").stat().st_mode) == 0o600
    assert not list(keys.glob("ca.key"))  # the CA's private key is not kept
    cfg = zenoh.Config.from_file(str(keys / "smart.json5"))
    acl = json.loads(cfg.get_json("access_control"))
    assert acl["enabled"] and acl["default_permission"] == "deny"
    subjects = {s["id"]: s["cert_common_names"] for s in acl["subjects"]}
    assert subjects["umbra"] == [common_name("trio", "umbra")] == ["umbra.trio.umbra"]
    rules = {r["id"]: r for r in acl["rules"]}
    puts = {
        p["subjects"][0]: sorted(
            k
            for rid in p["rules"]
            if rules[rid]["messages"] == ["put", "delete"] and rules[rid]["flows"] == ["ingress"]
            for k in rules[rid]["key_exprs"]
        )
        for p in acl["policies"]
    }
    assert puts == {"umbra": [KEY], "smart": [], "ui": ["umbra/trio/tick/count"]}
    tls = json.loads(cfg.get_json("transport/link/tls"))
    assert tls["enable_mtls"] is True and tls["listen_certificate"] == "smart.pem"


@dataclass
class Mesh:
    transports: dict[str, ZenohTransport]
    endpoints: dict[str, str]
    got: list[Message]


@pytest.fixture
def mesh(trio: tuple[GraphPlan, Path, Path]) -> Iterator[Mesh]:
    plan, keys, _other = trio
    names = ["umbra", "smart", "ui"]
    ports = dict(zip(names, free_loopback_ports(3), strict=True))
    endpoints = {n: f"tls/127.0.0.1:{p}" for n, p in ports.items()}
    transports: dict[str, ZenohTransport] = {}
    for i, name in enumerate(names):
        cfg = build_config(
            Endpoints([endpoints[name]], [endpoints[n] for n in names[:i]]),
            str(keys / f"{name}.json5"),
        )
        transports[name] = ZenohTransport(zenoh.open(cfg), plan, name)
    got: list[Message] = []
    link = next(k for k in plan.links if k.key == KEY)
    send = transports["umbra"].publisher(link)
    transports["smart"].subscribe(link, got.append)
    tick = next(k for k in plan.links if k.key != KEY)
    transports["ui"].publisher(tick)
    transports["smart"].subscribe(tick, lambda m: None)
    for t in transports.values():
        t.announce()
    assert transports["umbra"].wait_ready(threading.Event(), timeout=10)
    for i in range(1, 11):
        send(Scalar(value=float(i), seq=i), 0.0)
    wait_for(lambda: len(got) == 10, 10.0, "10 samples")
    yield Mesh(transports, endpoints, got)
    for t in transports.values():
        t.close()


def _attack(cfg: zenoh.Config, mesh: Mesh, admitted: int = 0) -> int:
    """Open a session with ``cfg`` to every process, pose as `umbra` and put commands on its
    key; the number of peers that let it in (``admitted``: how many should; the commands go
    once they have)."""
    cfg.insert_json5("connect/endpoints", json.dumps(list(mesh.endpoints.values())))
    session = zenoh.open(cfg)
    try:
        if admitted:
            wait_for(
                lambda: len(list(session.info.peers_zid())) >= admitted,
                20.0,
                f"{admitted} peers",
            )
        else:
            time.sleep(0.8)  # a window: the handshakes are refused, no peer appears in it
        peers = len(list(session.info.peers_zid()))
        token = session.liveliness().declare_token(
            alive_key("umbra/trio", "umbra", "none", str(session.zid()))
        )
        codec = Codec()
        for i in range(20):
            session.put(KEY, codec.encode(Scalar(value=-1.0, seq=100 + i)))
        time.sleep(0.3)  # a window: none of the commands may reach `smart`
        token.undeclare()
        return peers
    finally:
        session.close()


def _client(keys: Path, process: str | None) -> zenoh.Config:
    """A configuration with the CA of ``keys`` and, when given, ``process``'s certificate."""
    tls: dict[str, object] = {"root_ca_certificate": str(keys / "ca.pem")}
    if process is not None:
        for side in ("listen", "connect"):
            tls[f"{side}_private_key"] = str(keys / f"{process}.key")
            tls[f"{side}_certificate"] = str(keys / f"{process}.pem")
        tls["enable_mtls"] = True
    tls["verify_name_on_connect"] = False
    cfg = build_config(Endpoints())
    cfg.insert_json5("transport/link/tls", json.dumps(tls))
    return cfg


def _unchanged(mesh: Mesh) -> None:
    smart = mesh.transports["smart"]
    assert [m.value for m in mesh.got] == [float(i) for i in range(1, 11)]
    assert smart.stats()["token_conflicts"] == 0
    (sub,) = [s for s in smart.stats()["subscribe"] if s["key"] == KEY]
    assert sub["foreign"] == 0 and sub["received"] == 10  # zenoh stopped it before us
    assert "umbra" in smart.alive_processes()


def test_a_peer_without_a_certificate_is_refused(
    trio: tuple[GraphPlan, Path, Path], mesh: Mesh
) -> None:
    assert _attack(_client(trio[1], None), mesh) == 0
    _unchanged(mesh)


def test_a_certificate_of_another_ca_is_refused(
    trio: tuple[GraphPlan, Path, Path], mesh: Mesh
) -> None:
    _plan, _keys, other = trio
    assert _attack(_client(other, "umbra"), mesh) == 0  # the right name, the wrong CA
    _unchanged(mesh)


def test_a_valid_certificate_of_the_wrong_process_cannot_command(
    trio: tuple[GraphPlan, Path, Path], mesh: Mesh
) -> None:
    _plan, keys, _other = trio
    # let in: it is a process of the graph
    assert _attack(_client(keys, "ui"), mesh, admitted=3) == 3
    _unchanged(mesh)


def test_plain_tcp_beyond_loopback_is_refused_unless_insecure(
    capsys: pytest.CaptureFixture[str],
) -> None:
    graph = str(REPO / "graphs" / "counter_split.yaml")
    for args in (
        ("--process", "smart", "--listen", "tcp/0.0.0.0:7447"),
        ("--process", "umbra", "--connect", "tcp/192.168.1.10:7447"),
        ("--listen", "tcp/[::]:7447"),  # under the launcher too, before anything starts
    ):
        assert umbra_main(["run", graph, *args]) == 2
        err = capsys.readouterr().err
        assert "without TLS" in err and "umbra keys" in err, err
        assert "--insecure" in err and "Traceback" not in err
    check_exposure(["tcp/0.0.0.0:7447"], ["tcp/10.0.0.2:7447"], True, "x")  # --insecure
    check_exposure(["tls/0.0.0.0:7447", "tcp/127.0.0.1:1", "tcp/[::1]:2"], [], False, "x")
    check_exposure([], ["quic/robot.example:7447", "tcp/localhost:7447"], False, "x")
    check_exposure(["unixsock-stream//tmp/umbra.sock"], [], False, "x")  # never leaves the host
    for beyond in ("udp/0.0.0.0:7447", "ws/10.0.0.2:7447", "tcp/127.0.0.1.nip.io:7447"):
        with pytest.raises(UserError, match="without TLS"):
            check_exposure([beyond], [], False, "x")
    with pytest.raises(UserError, match=r"^x: error: refusing to connect to `tcp/robot\.example"):
        check_exposure([], ["tcp/robot.example:7447"], False, "x")


def test_keys_command_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    graph = str(REPO / "graphs" / "counter_split.yaml")
    out = str(tmp_path / "k")
    assert umbra_main(["keys", graph, "--out", out, "--host", "vision=1.2.3.4"]) == 2
    err = capsys.readouterr().err
    assert "PROCESS=ADDRESS" in err and "smart" in err
    assert umbra_main(["keys", graph, "--out", out, "--host", "smart=10.0.0.2"]) == 0
    assert "--zenoh-config" in capsys.readouterr().err
    assert umbra_main(["keys", graph, "--out", out]) == 2
    assert "not empty" in capsys.readouterr().err
    with pytest.raises(UserError, match="no zenoh configuration for process `ui`"):
        config_for(out, "ui")
    assert config_for(out, "smart") == str(tmp_path / "k" / "smart.json5")
