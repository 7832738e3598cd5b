"""Zenoh configuration: safe defaults, user files, endpoints; split-run command-line errors."""

from __future__ import annotations

import json
import socket
from pathlib import Path

import pytest
import zenoh

from tests.links.conftest import REPO, run_umbra
from umbra.connectors.errors import UserError
from umbra.runtime.links.config import (
    LEASE_MS,
    Endpoints,
    build_config,
    check_endpoint,
    default_mesh,
    free_loopback_ports,
    loopback_mesh,
)
from umbra.runtime.links.config_facts import config_facts
from umbra.runtime.links.session import open_session


def _get(cfg: zenoh.Config, key: str) -> object:
    return json.loads(cfg.get_json(key))


def test_default_config_is_peer_on_explicit_loopback_with_scouting_off() -> None:
    cfg = build_config(Endpoints(["tcp/127.0.0.1:7600"], ["tcp/127.0.0.1:7601"]))
    assert _get(cfg, "mode") == "peer"
    assert _get(cfg, "scouting/multicast/enabled") is False
    assert _get(cfg, "scouting/gossip/enabled") is False
    assert _get(cfg, "listen/endpoints") == ["tcp/127.0.0.1:7600"]
    assert _get(cfg, "connect/endpoints") == ["tcp/127.0.0.1:7601"]
    assert _get(cfg, "transport/link/tx/lease") == LEASE_MS
    assert _get(cfg, "transport/shared_memory/enabled") is True
    # zenoh's own default would listen on every interface: ours listens on nothing unless told
    assert _get(build_config(Endpoints()), "listen/endpoints") == []


def test_user_file_keeps_its_settings_but_never_scouts(tmp_path: Path) -> None:
    path = tmp_path / "z.json5"
    path.write_text("""{
      // a deployment file: a router to join, multicast (which we refuse), a longer lease
      mode: "client",
      connect: { endpoints: ["tcp/10.1.2.3:7447"] },
      scouting: { multicast: { enabled: true }, gossip: { enabled: true } },
      transport: { link: { tx: { lease: 3000 } } },
    }""")
    assert config_facts(str(path)).endpoints == Endpoints([], ["tcp/10.1.2.3:7447"])
    cfg = build_config(Endpoints(connect=["tcp/10.1.2.3:7447"]), str(path))
    assert _get(cfg, "mode") == "client"
    assert _get(cfg, "scouting/multicast/enabled") is False
    assert _get(cfg, "scouting/gossip/enabled") is False
    assert _get(cfg, "transport/link/tx/lease") == 3000
    assert _get(cfg, "listen/endpoints") == []


@pytest.mark.parametrize(
    "text, found",
    [
        ("{ mode: ", "not a valid zenoh configuration"),
        ("{ mode: 'emperor' }", "not a valid zenoh configuration"),
    ],
)
def test_bad_user_file_is_a_user_error(tmp_path: Path, text: str, found: str) -> None:
    path = tmp_path / "bad.json5"
    path.write_text(text)
    with pytest.raises(UserError, match=found) as err:
        build_config(Endpoints(), str(path))
    assert str(err.value).startswith(f"{path}")
    assert "\n" not in str(err.value) and ".rs" not in str(err.value)  # one line, no Rust path
    with pytest.raises(UserError, match=r"missing\.json5: error: cannot read .*: no such file"):
        build_config(Endpoints(), str(tmp_path / "missing.json5"))
    with pytest.raises(UserError, match="not a regular file"):
        build_config(Endpoints(), "/dev/zero")


def test_a_syntax_error_in_a_user_file_names_its_line(tmp_path: Path) -> None:
    path = tmp_path / "bad.json5"
    path.write_text('{\n  mode: "peer",\n  bogus: 1\n')
    with pytest.raises(UserError) as err:
        build_config(Endpoints(), str(path))
    assert str(err.value).startswith(f"{path}:3:"), str(err.value)
    assert str(err.value).count(": error: not a valid zenoh configuration: ") == 1


def test_endpoints_are_checked() -> None:
    assert check_endpoint(" tcp/127.0.0.1:7447 ", "--listen") == "tcp/127.0.0.1:7447"
    for bad in ("127.0.0.1:7447", "tcp:127.0.0.1", ""):
        with pytest.raises(UserError, match="--listen: expected a zenoh endpoint"):
            check_endpoint(bad, "--listen")


def test_meshes_join_every_pair_of_processes() -> None:
    mesh = loopback_mesh(["a", "b", "c"], [9001, 9002, 9003])
    assert mesh["a"] == Endpoints(["tcp/127.0.0.1:9001"], [])
    assert mesh["c"] == Endpoints(
        ["tcp/127.0.0.1:9003"], ["tcp/127.0.0.1:9001", "tcp/127.0.0.1:9002"]
    )
    assert default_mesh(["umbra", "smart"])["smart"].connect == ["tcp/127.0.0.1:7447"]
    ports = free_loopback_ports(3)
    assert len(set(ports)) == 3


def test_an_endpoint_in_use_is_a_user_error() -> None:
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        with pytest.raises(UserError, match=f"cannot open the zenoh session.*{port}") as raised:
            open_session(build_config(Endpoints([f"tcp/127.0.0.1:{port}"])))
    assert "holds that port" in str(raised.value) and "--listen ENDPOINT" in str(raised.value)


def test_split_run_command_line_errors(plugin_env: dict[str, str], tmp_path: Path) -> None:
    graph = str(REPO / "graphs" / "counter_split.yaml")
    done = run_umbra(plugin_env, tmp_path, "run", graph, "--clock", "sim")
    assert done.returncode == 2
    assert "runs on the real clock" in done.stderr and "--single-process" in done.stderr
    done = run_umbra(plugin_env, tmp_path, "run", graph, "--process", "smrt")
    assert done.returncode == 2
    assert "no process `smrt`" in done.stderr and "smart" in done.stderr
    done = run_umbra(
        plugin_env, tmp_path, "run", graph, "--process", "smart", "--connect", "localhost"
    )
    assert done.returncode == 2
    (line,) = [x for x in done.stderr.splitlines() if x.startswith("--connect:")]
    assert "expected a zenoh endpoint" in line
    assert "'localhost'" in done.stderr
