"""Credentials of processes started by hand, derived from the user's secret (real files)."""

from __future__ import annotations

import json
import os
import signal
import stat
import threading
from pathlib import Path

import pytest

from tests.links.conftest import (
    REPO,
    run_umbra,
    start_umbra,
    stop_all,
    watched_counter_graph,
)
from umbra.connectors.errors import UserError
from umbra.runtime.graph.check import load_graph
from umbra.runtime.links.auth import load_auth
from umbra.runtime.links.config import free_loopback_ports
from umbra.runtime.links.config_facts import config_facts
from umbra.runtime.links.host_auth import (
    HostSecret,
    host_credentials,
    load_secret,
    secret_folder,
    secret_name,
)

COUNTER = str(REPO / "graphs" / "counter_split.yaml")


def test_the_folder_is_the_users_runtime_folder_else_the_cache(tmp_path: Path) -> None:
    assert secret_folder({"XDG_RUNTIME_DIR": str(tmp_path)}) == tmp_path / "umbra"
    home = Path.home() / ".cache" / "umbra"
    assert secret_folder({}) == home
    assert secret_folder({"XDG_RUNTIME_DIR": "relative/dir"}) == home
    assert secret_folder({"XDG_RUNTIME_DIR": str(tmp_path / "missing")}) == home


def test_one_private_secret_per_graph_and_prefix_made_once(tmp_path: Path) -> None:
    folder = tmp_path / "a" / "umbra"  # made with its parent
    secret, path = load_secret("g", "umbra/g", folder)
    assert len(secret) == 32 and path.parent == folder
    assert stat.S_IMODE(folder.stat().st_mode) == 0o700
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    assert load_secret("g", "umbra/g", folder) == (secret, path)  # read, not made again
    assert load_secret("g", "other/g", folder)[0] != secret
    assert load_secret("h", "umbra/g", folder)[0] != secret
    assert secret_name("../../x y", "p").startswith("links-.._.._x_y-")  # stays in the folder
    assert sorted(p.name for p in folder.iterdir()) == sorted(
        secret_name(g, p) for g, p in (("g", "umbra/g"), ("g", "other/g"), ("h", "umbra/g"))
    )


def test_processes_starting_at_once_share_one_secret(tmp_path: Path) -> None:
    folder = tmp_path / "umbra"
    barrier = threading.Barrier(8)
    found: list[bytes] = []

    def start() -> None:
        barrier.wait()
        found.append(load_secret("race", "umbra/race", folder)[0])

    threads = [threading.Thread(target=start) for _ in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(found) == 8 and len(set(found)) == 1
    assert [p.name for p in folder.iterdir()] == [secret_name("race", "umbra/race")]  # no temp


@pytest.mark.parametrize("mode", [0o640, 0o604, 0o660, 0o700])
def test_a_secret_others_may_read_is_refused(tmp_path: Path, mode: int) -> None:
    _secret, path = load_secret("g", "umbra/g", tmp_path)
    path.chmod(mode)
    if mode == 0o700:  # executable by its owner only: still private
        assert load_secret("g", "umbra/g", tmp_path)[1] == path
        return
    with pytest.raises(UserError) as err:
        load_secret("g", "umbra/g", tmp_path)
    assert str(err.value).startswith(f"{path}: error: the link secret file must be private")
    assert f"found mode {mode:04o}" in str(err.value) and "--insecure" in str(err.value)


def test_a_folder_others_may_enter_a_foreign_owner_or_a_link_is_refused(tmp_path: Path) -> None:
    folder = tmp_path / "umbra"
    _secret, path = load_secret("g", "umbra/g", folder)
    folder.chmod(0o755)
    with pytest.raises(UserError, match=r"link secret folder must be private.*found mode 0755"):
        load_secret("g", "umbra/g", folder)
    folder.chmod(0o700)
    if os.geteuid() == 0:  # as root, give the file away
        os.chown(path, 65534, 65534)
        with pytest.raises(UserError, match=r"must belong to you \(uid 0\), found uid 65534"):
            load_secret("g", "umbra/g", folder)
        os.chown(path, 0, 0)
    target = tmp_path / "elsewhere"
    path.rename(target)
    path.symlink_to(target)
    with pytest.raises(UserError, match="cannot read the link secret"):
        load_secret("g", "umbra/g", folder)  # O_NOFOLLOW: not through a link
    path.unlink()
    path.write_text("not hex\n")
    path.chmod(0o600)
    with pytest.raises(UserError, match="expected a link secret of 64 hex digits"):
        load_secret("g", "umbra/g", folder)


def test_credentials_derive_from_the_secret_alone(tmp_path: Path) -> None:
    plan = load_graph(COUNTER)
    smart, umbra = (host_credentials(plan, p, tmp_path) for p in ("smart", "umbra"))
    again = host_credentials(plan, "smart", tmp_path)
    assert smart == again  # another start: the same credentials
    assert smart["password"] != umbra["password"] and len(smart["password"]) == 48
    assert smart["zid"] != umbra["zid"] and len(smart["zid"]) == 32
    assert smart["token_key"] == umbra["token_key"]
    dictionary = Path(smart["dictionary_file"])
    assert stat.S_IMODE(dictionary.stat().st_mode) == 0o600
    lines = dictionary.read_text().splitlines()
    observer = smart["observer"]
    assert observer == umbra["observer"] and observer["user"] == "observer@umbra"
    assert lines == [
        f"umbra:{umbra['password']}",
        f"smart:{smart['password']}",
        f"observer@umbra:{observer['password']}",
    ]
    # a peer is known by its user name when it connected to us, by its zenoh id when we did
    subjects = {s["id"]: s for s in smart["access_control"]["subjects"]}
    assert subjects["umbra"] == {"id": "umbra", "usernames": ["umbra"]}
    assert subjects["umbra#2"] == {"id": "umbra#2", "zids": [umbra["zid"]]}
    policy = next(p for p in smart["access_control"]["policies"] if p["id"] == "umbra: graph")
    assert policy["subjects"] == ["umbra", "umbra#2"]
    secret = bytes.fromhex(Path(smart["secret_file"]).read_text())
    assert HostSecret(secret).zid("umbra") == umbra["zid"]
    # the form the launcher's per-run files have
    path = tmp_path / "smart.json"
    path.write_text(json.dumps(smart))
    path.chmod(0o600)
    assert load_auth(str(path))["zid"] == smart["zid"]


def test_a_zenoh_configuration_that_authenticates_keeps_its_own(tmp_path: Path) -> None:
    plain = tmp_path / "plain.json5"
    plain.write_text('{ listen: { endpoints: ["tcp/127.0.0.1:7447"] } }')
    password = tmp_path / "usrpwd.json5"
    password.write_text('{ transport: { auth: { usrpwd: { user: "u", password: "p" } } } }')
    tls = tmp_path / "tls.json5"
    tls.write_text('{ transport: { link: { tls: { root_ca_certificate: "ca.pem" } } } }')
    assert not config_facts(None).authenticates and not config_facts(str(plain)).authenticates
    assert config_facts(str(password)).authenticates and config_facts(str(tls)).authenticates
    assert config_facts(str(tls)).tls and not config_facts(str(password)).tls


def test_run_refuses_a_secret_others_may_read_before_anything_starts(
    plugin_env: dict[str, str], tmp_path: Path
) -> None:
    (tmp_path / "g.yaml").write_text(watched_counter_graph("perm"))
    runtime_dir = tmp_path / "xdg"
    runtime_dir.mkdir(mode=0o700)
    env = dict(plugin_env, XDG_RUNTIME_DIR=str(runtime_dir))
    _secret, path = load_secret("perm", "umbra/perm", runtime_dir / "umbra")
    path.chmod(0o644)
    args = ("run", "g.yaml", "--process", "smart", "--duration", "0.3", "--out", "out")
    done = run_umbra(env, tmp_path, *args)
    assert done.returncode == 2, done.stderr
    (line,) = done.stderr.strip().splitlines()
    assert line.startswith(f"{path}: error: the link secret file must be private (mode 0600)")
    assert "found mode 0644" in line and "Traceback" not in done.stderr
    assert not (tmp_path / "out" / "summary-smart.json").exists()
    # --insecure: no secret read or made, the process runs
    path.unlink()
    done = run_umbra(env, tmp_path, *args, "--insecure")
    assert done.returncode == 0, done.stderr
    assert not path.exists() and "links authenticated" not in done.stderr


def test_a_folder_that_cannot_be_made_is_a_user_error(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(UserError, match=r"cannot make the link secret there.*--insecure"):
        load_secret("g", "umbra/g", blocker / "umbra")


def test_a_consumer_that_connects_knows_its_producer_by_the_derived_zenoh_id(
    plugin_env: dict[str, str], tmp_path: Path
) -> None:
    """The producer listens and the consumer connects: the producer shows no password on that
    link, and the consumer's rules let it in by the zenoh id derived for it."""
    (port,) = free_loopback_ports(1)
    endpoint = f"tcp/127.0.0.1:{port}"
    common = ("run", COUNTER, "--out", "out")
    consumer = start_umbra(plugin_env, tmp_path, *common, "--process", "smart", "--connect",
                           endpoint)  # fmt: skip
    producer = start_umbra(plugin_env, tmp_path, *common, "--process", "umbra", "--listen",
                           endpoint)  # fmt: skip
    try:
        assert producer.finish(timeout=30) == 0, producer.text  # its 200 samples, then it stops
        consumer.wait_for("process `umbra` stopped (its streams ended)")
        consumer.popen.send_signal(signal.SIGINT)
        assert consumer.finish() == 130, consumer.text
    finally:
        stop_all([consumer, producer])
    summary = json.loads((tmp_path / "out" / "summary-smart.json").read_text())
    (sub,) = summary["links"]["subscribe"]
    assert sub["received"] == 200 and sub["missing"] == 0 and sub["foreign"] == 0
    assert "links authenticated with this user's secret" in consumer.text


def test_a_configuration_through_a_router_is_named_as_not_authenticated(tmp_path: Path) -> None:
    client = tmp_path / "client.json5"
    client.write_text('{ mode: "client" }')
    peer = tmp_path / "peer.json5"
    peer.write_text('{ mode: "peer" }')
    assert config_facts(str(client)).routed_mode == "client"
    assert config_facts(str(peer)).routed_mode == "" and config_facts(None).routed_mode == ""
