"""The launcher's per-run credentials and the access rules derived from the graph."""

from __future__ import annotations

import json
import os
import stat
from collections.abc import Callable
from pathlib import Path

import pytest

from tests.links.conftest import REPO, Running
from umbra.connectors.errors import UserError
from umbra.runtime.graph.check import load_graph
from umbra.runtime.links.acl import by_username, link_keys, zenoh_acl
from umbra.runtime.links.auth import RunCredentials, load_auth

COUNTER = str(REPO / "graphs" / "counter_split.yaml")
KEY = "umbra/counter_split/counter/count"


def test_credentials_are_private_per_process_and_removed_with_the_run() -> None:
    plan = load_graph(COUNTER)
    creds = RunCredentials(plan)
    try:
        assert stat.S_IMODE(creds.folder.stat().st_mode) == 0o700
        umbra, smart = (load_auth(str(creds.files[p])) for p in ("umbra", "smart"))
        assert (umbra["user"], smart["user"]) == ("umbra", "smart")
        assert umbra["password"] != smart["password"] and len(umbra["password"]) == 48
        assert umbra["token_key"] == smart["token_key"] and len(umbra["token_key"]) == 64
        dictionary = Path(umbra["dictionary_file"])
        assert stat.S_IMODE(dictionary.stat().st_mode) == 0o600
        lines = dictionary.read_text().splitlines()
        observer = umbra["observer"]
        assert observer == smart["observer"] and observer["user"] == "observer@umbra"
        assert lines == [
            f"umbra:{umbra['password']}",
            f"smart:{smart['password']}",
            f"observer@umbra:{observer['password']}",
        ]
        # `smart` connects to `umbra` (mesh order): it knows it by the zenoh id it was given
        subjects = {s["id"]: s for s in smart["access_control"]["subjects"]}
        assert subjects["umbra"] == {"id": "umbra", "zids": [umbra["zid"]]}
        assert {s["id"]: s for s in umbra["access_control"]["subjects"]}["smart"] == {
            "id": "smart",
            "usernames": ["smart"],
        }
    finally:
        creds.close()
    assert not creds.folder.exists()


def test_credentials_readable_by_others_are_refused(tmp_path: Path) -> None:
    path = tmp_path / "auth.json"
    path.write_text(json.dumps({"user": "u", "password": "p", "dictionary_file": "d"}))
    os.chmod(path, 0o644)
    with pytest.raises(UserError, match=r"must be private.*0644"):
        load_auth(str(path))
    os.chmod(path, 0o600)
    assert load_auth(str(path))["user"] == "u"
    path.write_text(json.dumps({"user": "u"}))
    with pytest.raises(UserError, match="expected link credentials"):
        load_auth(str(path))


def test_rules_let_each_process_publish_only_its_outputs() -> None:
    plan = load_graph(COUNTER)
    produces, consumes = link_keys(plan)
    assert produces == {"umbra": {KEY}, "smart": set()}
    assert consumes == {"umbra": set(), "smart": {KEY}}
    acl = zenoh_acl(plan, by_username)
    assert acl["default_permission"] == "deny"
    rules = {r["id"]: r for r in acl["rules"]}
    granted = {
        (p["subjects"][0], m, f, k)
        for p in acl["policies"]
        for rid in p["rules"]
        for m in rules[rid]["messages"]
        for f in rules[rid]["flows"]
        for k in rules[rid]["key_exprs"]
    }
    assert ("umbra", "put", "ingress", KEY) in granted
    assert not any(s == "smart" and m == "put" and f == "ingress" for s, m, f, _k in granted)
    tokens = {(s, k) for s, m, f, k in granted if m == "liveliness_token" and f == "ingress"}
    assert tokens == {
        ("umbra", "umbra/counter_split/_alive/umbra/**"),
        ("smart", "umbra/counter_split/_alive/smart/**"),
    }


@pytest.mark.slow
def test_the_launcher_runs_every_process_over_mutual_tls_with_the_keys(
    umbra: Callable[..., Running], tmp_path: Path
) -> None:
    from umbra.runtime.cli.main import main

    assert main(["keys", COUNTER, "--out", str(tmp_path / "keys")]) == 0
    run = umbra("run", COUNTER, "--zenoh-config", "keys/", "--out", "out")
    assert run.finish() == 0, run.text
    assert "listening on tls/127.0.0.1:" in run.text
    summary = json.loads((tmp_path / "out" / "summary-smart.json").read_text())
    (sub,) = summary["links"]["subscribe"]
    assert sub["received"] == 200 and sub["missing"] == 0
