"""One operator per browser across the pages of one server (pure: no server, no browser).

The console's page and the Active Sketch page of one browser are one operator: control taken
on either is held on both; a viewer in another browser is refused and counted."""

from __future__ import annotations

from umbra.modules.operator.control import ControlArbiter
from umbra.modules.webdoor.viewer import viewer_key


def test_control_taken_on_one_page_is_held_on_every_page_of_the_browser() -> None:
    a = ControlArbiter()
    a.join("console-1", "viewer 1 (127.0.0.1)", browser="alice")
    a.join("sketch-1", "viewer 1 (127.0.0.1)", browser="alice")
    a.join("sketch-2", "sketch viewer 1 (127.0.0.1)", browser="bob")
    assert not a.may_command("sketch-1", "vcr play").ok  # nobody holds control yet
    assert a.take("sketch-1").ok and a.person_acted
    assert a.holder == "console-1"  # the browser's first page: the console says "(you)"
    assert a.holds("console-1") and a.holds("sketch-1") and not a.holds("sketch-2")
    assert a.may_command("console-1", "abort").ok and a.may_command("sketch-1", "vcr play").ok
    refused = a.may_command("sketch-2", "vcr play")
    assert not refused.ok
    assert refused.message == "refused vcr play: viewer 1 (127.0.0.1) holds control"
    assert not a.take("sketch-2").ok and not a.release("sketch-2").ok
    assert a.take("console-1").message == "you already hold control"
    # released from the other page of the same browser: free for everyone
    assert a.release("sketch-1").ok and a.holder is None
    assert a.take("sketch-2").ok and a.holder == "sketch-2"
    assert not a.may_command("console-1", "click").ok
    assert a.refused == 5  # 1 before anyone held control, 3 of bob's, 1 of alice's console


def test_control_stays_while_a_page_of_the_browser_is_open() -> None:
    a = ControlArbiter()
    a.join("console-1", "viewer 1", browser="alice")
    a.join("sketch-1", "viewer 1", browser="alice")
    a.join("console-2", "viewer 2", browser="bob")
    assert a.take("console-1").ok
    assert not a.leave("console-1")  # the sketch page of the browser still holds it
    assert a.holder == "sketch-1" and a.holder_name() == "viewer 1"
    assert a.may_command("sketch-1", "snapshot").ok
    assert a.leave("sketch-1") and a.holder is None  # the browser's last page: free
    assert a.take("console-2").ok


def test_pages_without_a_browser_key_are_operators_on_their_own() -> None:
    a = ControlArbiter()
    a.join("s1", "alice")  # e.g. a websocket client that is not a browser: no cookie
    a.join("s2", "bob")
    assert a.take("s1").ok
    assert not a.holds("s2") and not a.may_command("s2", "click").ok
    assert a.holder_browser() == "" and a.name_in("") == ""


def test_viewer_keys_hash_the_cookie_and_refuse_malformed_ones() -> None:
    key = viewer_key("Yq3-_0abcdefghijklmnopq")
    assert len(key) == 16 and key == viewer_key("Yq3-_0abcdefghijklmnopq")
    assert "Yq3" not in key and key != viewer_key("Yq3-_0abcdefghijklmnopr")
    for bad in (None, "", "short", "has space in it 1234567", "x" * 65, "é" * 20):
        assert viewer_key(bad) == ""


def test_a_console_page_opened_after_the_sketch_page_stands_for_its_browser() -> None:
    a = ControlArbiter()
    a.join("sketch-1", "sketch viewer 1", browser="alice", lead=False)
    assert a.take("sketch-1").ok and a.holder == "sketch-1"
    a.join("console-1", "viewer 1", browser="alice")  # its page compares sessions: "(you)"
    assert a.holder == "console-1" and a.holds("sketch-1")
    a.join("console-2", "viewer 2", browser="bob")
    assert a.holder == "console-1" and not a.holds("console-2")
    assert not a.leave("console-1") and a.holder == "sketch-1"  # the follower keeps it
    a.join("sketch-3", "sketch viewer 3", browser="alice", lead=False)
    assert not a.leave("sketch-1") and a.holder == "sketch-3"
    assert a.leave("sketch-3") and a.holder is None
