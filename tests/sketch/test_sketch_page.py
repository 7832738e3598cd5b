"""SketchPage on a real loopback web server, without a browser: the page's state, its checked
commands, one operator (the holder of control, shared with the console of the same server) and
the viewers refused and counted, the access token on every route, and a lost page pausing the
path it set moving; and, in real Chromium, one holder for the console and the sketch page of
one browser, and a second page without control that cannot play.

A "browser" here is an ``httpx.Client``: it keeps the viewer cookie the server gives it on its
first request, as a browser does. A stepping thread plays the scheduler (one thread for every
module of the process, as the scheduler's tick lock makes it)."""

from __future__ import annotations

import json
import logging
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import cv2
import httpx
import numpy as np
import pytest
from websockets.sync.client import connect

from tests.operator.browser import chromium, needs_chromium
from tests.poll import wait_for
from umbra.connectors.messages import Image, ZoomState
from umbra.connectors.path_messages import VcrMode, VcrState
from umbra.connectors.ptu_messages import PtuState
from umbra.connectors.sketch_messages import SketchPrimitive
from umbra.connectors.states import Outcome, Verdict
from umbra.modules.operator.console import OperatorConsole
from umbra.modules.sketch_page import page_web
from umbra.modules.sketch_page.sketch_page import SketchPage
from umbra.runtime.harness import ModuleHarness


class Stepper(threading.Thread):
    """Steps the harnesses in turn every 10 ms (one scheduler thread for the process); pushes
    from the test thread go through :meth:`push`."""

    def __init__(self, *harnesses: ModuleHarness) -> None:
        super().__init__(daemon=True)
        self.harnesses = harnesses
        self._pushes: list[tuple[ModuleHarness, str, Any]] = []
        self._lock = threading.Lock()
        self._halt = threading.Event()

    def push(self, h: ModuleHarness, port: str, sample: Any) -> None:
        with self._lock:
            self._pushes.append((h, port, sample))

    def run(self) -> None:
        while not self._halt.is_set():
            with self._lock:
                pushes, self._pushes = self._pushes, []
                for h, port, sample in pushes:
                    h.push(port, sample)
                for h in self.harnesses:
                    h.step(dt=0.01)
            time.sleep(0.01)

    def commands(self, h: ModuleHarness) -> list[str]:
        with self._lock:
            return [m.text for m in h.outputs("command")]

    def __enter__(self) -> Stepper:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._halt.set()
        self.join(5)


class Browser:
    """One browser on the page: keeps its cookies (the viewer cookie: one operator)."""

    def __init__(self, url: str) -> None:
        self.root, _, query = url.partition("/sketch")
        # a browser's page sends its own Origin on a POST; the token in the address is swapped
        # for a cookie and a redirect to the address without it
        self.client = httpx.Client(timeout=10, follow_redirects=True, headers={"Origin": self.root})
        assert self.client.get(self.root + "/sketch" + query).status_code == 200  # the page
        assert self.client.cookies.get("umbra_viewer")

    def state(self) -> dict:
        reply = self.client.get(self.root + "/sketch/state")
        assert reply.status_code == 200, reply.text
        return reply.json()

    def command(self, text: str) -> tuple[int, dict]:
        reply = self.client.post(self.root + "/sketch/command", content=json.dumps({"text": text}))
        return reply.status_code, reply.json()

    def control(self, action: str) -> tuple[int, dict]:
        reply = self.client.post(
            self.root + "/sketch/control", content=json.dumps({"action": action})
        )
        return reply.status_code, reply.json()

    def close(self) -> None:
        self.client.close()


def _what(text: str) -> str:
    """How the page names a command in its replies: the verb, with the action or macro."""
    words = text.split()
    return " ".join(words[:2]) if words[0] in ("vcr", "plan") else words[0]


@contextmanager
def _page(**params: Any) -> Iterator[tuple[ModuleHarness, Stepper]]:
    with ModuleHarness(SketchPage, params) as h, Stepper(h) as stepper:
        yield h, stepper


def test_state_menus_and_checked_commands() -> None:
    triad = SketchPrimitive(
        primitive_id="triad1",
        kind="triad",
        points=np.array([[0.5, 0, 0.3], [0.7, 0, 0.3], [0.5, 0.2, 0.3], [0.5, 0, 0.5]]),
        covariances=np.stack([np.eye(3) * 1e-6] * 4),
        edges=np.array([[0, 1], [0, 2], [0, 3]]),
    )
    with _page() as (h, stepper):
        stepper.push(h, "primitive", triad)
        op = Browser(h.module.url)
        state = wait_for(op.state, 5.0, "the first state", ok=lambda s: s["version"] > 0)
        assert state["menus"]["point"][0][0] == "move_to"
        assert state["menus"]["none"][1][0] == "stow"
        entry = state["primitives"][0]
        assert entry["centroid_m"] == [0.55, 0.05, 0.35] and entry["sigma_mm"] == [1.0] * 4
        assert state["menu"] == [
            ["make_box", "keep the box as scene geometry (no motion)", "Make box"]
        ]
        assert state["menus"]["line"][0][2] == "Grab pipe"  # the button's label: words
        name = wait_for(lambda: op.state()["control"]["you"], 5.0, "a name")
        assert op.control("take") == (200, {"ok": True, "message": f"{name} took control"})
        assert op.command("aim 0.55 0.05 0.35 0.3") == (200, {"ok": True, "message": "sent aim"})
        code, reply = op.command("vcr speed 7")
        assert code == 400 and "expected a speed within 0.1 .. 1" in reply["error"]
        code, reply = op.command("place line 1,nan 2,2 | 3,3 4,4")
        assert code == 400 and "must be finite" in reply["error"]
        code, reply = op.control("steal")
        assert code == 400 and 'expected {"action": "take" or "release"}' in reply["error"]
        assert op.command("plan make_box triad1")[0] == 200
        assert stepper.commands(h) == ["aim 0.55 0.05 0.35 0.3", "plan make_box triad1"]
        assert op.state()["control"]["refused"] == 3  # the malformed ones
        op.close()


def test_the_cameras_ptus_and_zoom_reach_the_page_as_they_report_and_silence_is_said() -> None:
    """Camera a's PTU slewing, then still; its zoom; camera b wired to nothing. Once the PTU
    and the zoom stop reporting for ``device_silent_s``, the page says so, not "still"."""
    with _page(device_silent_s=0.3) as (h, stepper):
        op = Browser(h.module.url)

        def camera(side: str, ok) -> dict:
            state = wait_for(
                op.state, 5.0, f"camera {side}", ok=lambda s: ok(s["cameras"][ord(side) - 97])
            )
            return state["cameras"][ord(side) - 97]

        stepper.push(h, "ptu_a", PtuState(pan=0.5, tilt=-0.1, moving=True))
        stepper.push(h, "zoom_a", ZoomState(zoom=0.304, moving=False))
        a = camera("a", lambda c: c["ptu"] is not None and c["zoom"] is not None)
        assert a["ptu"] == {
            "moving": True,
            "pan_deg": 28.6,
            "tilt_deg": -5.7,
            "ok": True,
            "status": "ok",
            "silent": False,
        }
        assert a["zoom"] == {
            "zoom": 0.3,
            "moving": False,
            "ok": True,
            "status": "ok",
            "silent": False,
        }
        assert a["still"] is False
        b = op.state()["cameras"][1]
        assert b == {"side": "b", "ptu": None, "zoom": None, "still": False}

        def still_and_reporting() -> bool:
            stepper.push(h, "ptu_a", PtuState(pan=0.52, tilt=-0.1, moving=False))
            stepper.push(h, "zoom_a", ZoomState(zoom=0.304, moving=False))
            return bool(op.state()["cameras"][0]["still"])

        wait_for(still_and_reporting, 5.0, "camera a still")
        silent = camera("a", lambda c: c["ptu"]["silent"] and c["zoom"]["silent"])
        assert silent["still"] is False and silent["ptu"]["moving"] is False
        op.close()


def test_the_macro_verdict_and_the_live_camera_reach_the_page() -> None:
    with _page() as (h, stepper):
        op = Browser(h.module.url)
        assert op.client.get(op.root + "/sketch/live/a.jpg").status_code == 404  # no frame yet
        pixels = np.zeros((120, 160, 3), np.uint8)
        pixels[30:90, 40:120] = (0, 0, 255)  # a red box, BGR
        stepper.push(h, "live_a", Image(pixels=pixels, frame="cam_left"))
        text = "missed: gripper closed 11.0 mm off the pipe axis, 0.4 deg off it"
        stepper.push(
            h,
            "verdict",
            Verdict(
                stage="grab_pipe",
                message=text,
                values={"grasp_distance_mm": 11.0},
                outcome=Outcome.MISSED,
            ),
        )
        state = wait_for(op.state, 5.0, "the verdict", ok=lambda s: s.get("verdict"))
        assert state["verdict"] == {
            "macro": "grab_pipe",
            "label": "Grab pipe",
            "text": text,
            "outcome": "missed",
            "success": False,
        }
        reply = wait_for(
            lambda: op.client.get(op.root + "/sketch/live/a.jpg"),
            5.0,
            "the live image",
            ok=lambda r: r.is_success,
        )
        assert reply.headers["content-type"] == "image/jpeg"
        frame = cv2.imdecode(np.frombuffer(reply.content, np.uint8), cv2.IMREAD_COLOR)
        assert frame.shape == (120, 160, 3)
        assert frame[60, 80, 2] > 200 and frame[60, 80, 1] < 60  # red inside the box
        assert frame[10, 10].max() < 40  # black outside it
        # every poll of the same frame gets the one encoding; a new frame is encoded once more
        polls = [op.client.get(op.root + "/sketch/live/a.jpg") for _ in range(3)]
        assert {p.content for p in polls} == {reply.content}
        assert h.module.web.live_encodes["a"] == 1
        stepper.push(h, "live_a", Image(pixels=255 - pixels, frame="cam_left"))
        newer = wait_for(
            lambda: op.client.get(op.root + "/sketch/live/a.jpg"),
            5.0,
            "a newer live image",
            ok=lambda r: r.content != reply.content,
        )
        assert (
            cv2.imdecode(np.frombuffer(newer.content, np.uint8), cv2.IMREAD_COLOR)[10, 10].min()
            > 200
        )
        assert h.module.web.live_encodes["a"] == 2
        assert op.client.get(op.root + "/sketch/live/b.jpg").status_code == 404
        assert op.client.get(op.root + "/sketch/live/c.jpg").status_code == 404
        op.close()


def test_a_viewer_without_control_is_refused_and_counted_the_holder_passes(
    caplog: pytest.LogCaptureFixture,
) -> None:
    caplog.set_level(logging.INFO)
    with _page() as (h, stepper):
        alice, bob = Browser(h.module.url), Browser(h.module.url)
        a_name = wait_for(lambda: alice.state()["control"]["you"], 5.0, "alice's name")
        b_name = wait_for(lambda: bob.state()["control"]["you"], 5.0, "bob's name")
        assert a_name != b_name and a_name.startswith("sketch viewer ")
        # nobody holds control: nobody commands
        code, reply = alice.command("snapshot")
        assert code == 403 and reply["error"] == "refused snapshot: take control first"
        assert alice.control("take")[0] == 200
        # every page shows the holder; only the holder's says "mine"
        assert alice.state()["control"]["mine"] and not bob.state()["control"]["mine"]
        assert bob.state()["control"]["holder"] == a_name
        # the viewer's commands, each verb of the page, are refused with the holder's name
        texts = [
            "snapshot",
            "aim 0.6 0 0.3 0.2",
            "zoom 0.4",
            "place point 320,240 | 322,240",
            "plan grab_pipe line1",
            "plan make_box triad1",
            "vcr play",
            "vcr pause",
            "vcr back 0.5",
            "vcr resume",
            "vcr speed 0.5",
            "vcr seek 0.3",
        ]
        for text in texts:
            code, reply = bob.command(text)
            assert (code, reply["error"]) == (
                403,
                f"refused {_what(text)}: {a_name} holds control",
            ), text
        code, reply = bob.control("take")  # a second operator
        assert code == 403 and f"{a_name} holds control" in reply["error"]
        assert bob.control("release")[1]["error"] == "refused: you do not hold control"
        assert stepper.commands(h) == []  # nothing reached Sketch
        refused = 1 + len(texts) + 2  # alice's before she took control, bob's
        assert h.module.summary()["control_refused"] == refused
        assert bob.state()["control"]["refused"] == refused  # shown on every page
        assert f"{b_name}: refused vcr play: {a_name} holds control" in caplog.text
        # the holder's commands go through
        for text in texts:
            assert alice.command(text) == (200, {"ok": True, "message": f"sent {_what(text)}"})
        assert stepper.commands(h) == texts
        # control passes: released, taken by the other browser
        assert alice.control("release")[0] == 200
        wait_for(lambda: bob.state()["control"]["holder"] == "", 5.0, "control released")
        assert bob.control("take")[0] == 200
        assert alice.command("vcr play")[0] == 403
        assert bob.command("vcr play")[0] == 200
        # a client that never loaded the page (the token's cookie, no viewer cookie) cannot
        bare = httpx.post(
            alice.root + "/sketch/command",
            content=json.dumps({"text": "vcr play"}),
            cookies={"umbra_token": h.module.url.split("?token=")[1]},
            headers={"x-umbra-csrf": "1"},
            timeout=5,
        )
        assert bare.status_code == 403 and "no viewer cookie" in bare.json()["error"]
        assert h.module.summary()["control_refused"] == refused + 2
        alice.close()
        bob.close()


def test_a_silent_browser_leaves_and_its_control_is_free() -> None:
    with _page(lost_after=0.4) as (h, _):
        alice, bob = Browser(h.module.url), Browser(h.module.url)
        wait_for(
            lambda: alice.state()["control"]["you"] and bob.state()["control"]["you"],
            5.0,
            "both names",
        )
        assert alice.control("take")[0] == 200
        control = h.module._control
        assert len(control.sessions) == 2
        end = time.monotonic() + 1.0
        while time.monotonic() < end:  # bob keeps polling, alice is gone
            bob.state()
            time.sleep(0.1)
        assert control.holder is None and len(control.sessions) == 1
        assert bob.control("take")[0] == 200
        assert bob.command("snapshot")[0] == 200
        alice.close()
        bob.close()


class ConsolePage:
    """The console's websocket as a browser's page opens it: with the browser's cookies."""

    def __init__(self, console_url: str, cookies: httpx.Cookies) -> None:
        jar = "; ".join(f"{k}={v}" for k, v in cookies.items())
        ws_url = console_url.split("?")[0].replace("http://", "ws://").rstrip("/") + "/ws"
        self.ws = connect(ws_url, open_timeout=5, additional_headers={"Cookie": jar})
        welcome = self.recv("welcome")
        self.session, self.name, self.seq = welcome["session"], welcome["name"], 0

    def send(self, type_: str, **fields: Any) -> None:
        self.seq += 1
        message = {"session": self.session, "seq": self.seq, "type": type_, **fields}
        self.ws.send(json.dumps(message))

    def recv(self, kind: str, timeout: float = 5.0) -> dict:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            msg = self.ws.recv(timeout=max(0.01, end - time.monotonic()))
            if isinstance(msg, str) and json.loads(msg).get("type") == kind:
                return json.loads(msg)
        raise TimeoutError(kind)

    def close(self) -> None:
        self.ws.close()


def test_one_holder_for_the_console_and_the_sketch_page_of_one_server() -> None:
    with (
        ModuleHarness(OperatorConsole, {}) as console,
        ModuleHarness(SketchPage, {}) as sketch,
        Stepper(console, sketch) as stepper,
    ):
        server = console.module._server
        assert sketch.module._server is server and console.module.arbiter is server.control
        assert sketch.module.url == console.module.url.replace("/?", "/sketch?")
        # one person: the console page and the sketch page in one browser
        alice = Browser(sketch.module.url)
        alice_console = ConsolePage(console.module.url, alice.client.cookies)
        arbiter = console.module.arbiter
        wait_for(lambda: alice_console.session in arbiter.sessions, 5.0, "alice's session")
        alice_name = wait_for(lambda: alice.state()["control"]["you"], 5.0, "alice's name")
        assert alice_name == alice_console.name  # one browser, one name
        bob = Browser(sketch.module.url)  # another person, on the sketch page only
        bob_name = wait_for(lambda: bob.state()["control"]["you"], 5.0, "bob's name")
        # control taken on the console is control on the sketch page
        alice_console.send("take")
        wait_for(lambda: arbiter.holder == alice_console.session, 5.0, "alice holding control")
        wait_for(lambda: alice.state()["control"]["mine"], 5.0, "alice's control")
        assert alice.command("snapshot")[0] == 200
        code, reply = bob.command("vcr play")
        assert code == 403 and reply["error"] == f"refused vcr play: {alice_name} holds control"
        assert bob.control("take")[0] == 403
        assert stepper.commands(sketch) == ["snapshot"]
        # released on the sketch page: free on the console too; taken on the sketch page by
        # the other person, the console's holder is refused
        assert alice.control("release")[0] == 200
        wait_for(lambda: arbiter.holder is None, 5.0, "control released")
        assert bob.control("take")[0] == 200
        alice_console.send("action", action="abort")
        wait_for(lambda: console.module.counts["refused"] == 1, 5.0, "a refusal")
        assert not console.outputs("operator")
        notice = console.module.board.lines[-1].text
        assert notice == f"refused abort: {bob_name} holds control"
        assert arbiter.holder_name() == bob_name
        # taken back on the sketch page by the first person: the console page holds it too
        assert bob.control("release")[0] == 200
        assert alice.control("take")[0] == 200
        assert arbiter.holder == alice_console.session  # the console page says "(you)"
        alice_console.send("action", action="abort")
        wait_for(lambda: console.module.counts["abort"] == 1, 5.0, "an abort")
        assert console.output("operator").action == "abort"
        # the console page closes: the sketch page of the same browser keeps control
        alice_console.close()
        wait_for(lambda: alice_console.session not in arbiter.sessions, 5.0, "alice's session gone")
        assert arbiter.holder_name() == alice_name
        assert alice.command("vcr pause")[0] == 200
        assert bob.command("vcr play")[0] == 403
        alice.close()
        bob.close()


def test_every_route_of_the_page_needs_the_token(tmp_path: Path) -> None:
    token_file = tmp_path / "token"
    token_file.write_text("s3cret-token-for-the-sketch\n")
    with _page(token_file=str(token_file)) as (h, _):
        url = h.module.url
        assert url.endswith("/sketch?token=s3cret-token-for-the-sketch")
        root = url.split("/sketch")[0]
        routes = [
            ("GET", "/sketch"),
            ("GET", "/sketch/sketch.js"),
            ("GET", "/sketch/state"),
            ("GET", "/sketch/image/a.jpg"),
            ("GET", "/sketch/live/a.jpg"),
            ("POST", "/sketch/command"),
            ("POST", "/sketch/control"),
        ]
        for method, path in routes:
            for query in ("", "?token=guess-guess-guess-guess"):
                reply = httpx.request(method, root + path + query, content=b"{}", timeout=5)
                assert reply.status_code == 403, (method, path, query)
                assert b"access token" in reply.content
        # a POST needs the cookie: the token in its address is not enough
        posted = httpx.post(root + "/sketch/control?token=s3cret-token-for-the-sketch", timeout=5)
        assert posted.status_code == 403 and b"cookie" in posted.content
        assert h.module._server.refused_requests == 2 * len(routes) + 1
        # the address with the token: the page, and its requests carry the cookie it sets
        op = Browser(url)
        assert op.client.cookies.get("umbra_token") == "s3cret-token-for-the-sketch"
        wait_for(lambda: op.state()["control"]["you"], 5.0, "a name")
        assert op.control("take")[0] == 200
        assert op.command("snapshot")[0] == 200
        # another site's page cannot post to it, even with the cookies
        evil = op.client.post(
            root + "/sketch/command",
            content=json.dumps({"text": "vcr play"}),
            headers={"Origin": "http://evil.example"},
        )
        assert evil.status_code == 403 and b"another site" in evil.content
        op.close()


def test_beyond_loopback_the_page_makes_a_token_and_prints_it(
    caplog: pytest.LogCaptureFixture,
) -> None:
    caplog.set_level(logging.INFO)
    with _page(host="0.0.0.0") as (h, _):
        token = h.module.url.split("?token=")[1]
        assert len(token) >= 20
        port = h.module._server.port
        assert f"Active Sketch page: http://127.0.0.1:{port}/sketch?token={token}" in caplog.text
        assert httpx.get(f"http://127.0.0.1:{port}/sketch/state", timeout=5).status_code == 403
        reply = httpx.get(
            f"http://127.0.0.1:{port}/sketch/state?token={token}", follow_redirects=True, timeout=5
        )
        assert reply.status_code == 200 and "control" in reply.json()


def test_a_request_step_never_answered_is_dropped_not_sent_late(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(page_web, "REPLY_TIMEOUT_S", 0.3)
    with ModuleHarness(SketchPage, {}) as h:  # nobody steps it
        op = Browser(h.module.url)
        code, reply = op.command("snapshot")
        assert code == 503 and "did not answer within" in reply["error"]
        h.step(0.05)
        assert h.outputs("command") == []
        op.close()


@pytest.mark.parametrize("mode", [VcrMode.PLAYING, VcrMode.AT_STOP, VcrMode.GRIPPING])
def test_a_lost_page_pauses_the_path_it_set_moving(mode: VcrMode) -> None:
    """Also while the path waits at a stop point for the gripper: it goes on after that."""
    with _page(lost_after=0.4) as (h, stepper):
        op = Browser(h.module.url)
        wait_for(lambda: op.state()["control"]["you"], 5.0, "a name")
        assert op.control("take")[0] == 200
        assert op.command("vcr play")[0] == 200
        stepper.push(h, "vcr_state", VcrState(path_id="path1", mode=mode, progress=0.1))
        for _ in range(8):  # the page keeps polling: nothing happens
            op.state()
            time.sleep(0.1)
        assert stepper.commands(h) == ["vcr play"]
        time.sleep(0.6)  # the page is gone
        wait_for(lambda: stepper.commands(h) == ["vcr play", "vcr pause"], 5.0, "play, then pause")
        assert h.module.summary()["paused_for_lost_page"] == 1
        time.sleep(0.2)  # once
        assert len(stepper.commands(h)) == 2
        assert h.module._control.holder is None  # its browser left: control is free
        # a page that paused the path itself is not paused again when it goes
        op.state()
        assert op.control("take")[0] == 200
        assert op.command("vcr pause")[0] == 200
        time.sleep(0.6)  # a window: no second pause comes
        assert stepper.commands(h) == ["vcr play", "vcr pause", "vcr pause"]
        op.close()


@pytest.mark.browser
@needs_chromium
def test_in_chromium_one_holder_for_both_pages_and_a_viewer_cannot_play() -> None:
    with (
        ModuleHarness(OperatorConsole, {}) as console,
        ModuleHarness(SketchPage, {}) as sketch,
        Stepper(console, sketch) as stepper,
        chromium() as browser,
    ):
        # one person: the console and the sketch page in one browser; control taken on the
        # console is control on the sketch page
        person = browser.new_context(viewport={"width": 1400, "height": 900})
        desk = person.new_page()
        desk.goto(console.module.url)
        desk.wait_for_function("window.umbra.session && window.umbra.state", timeout=20000)
        desk.click("#take")
        desk.wait_for_function(
            "window.umbra.state.control_session === window.umbra.session", timeout=10000
        )
        name = desk.evaluate("window.umbra.name")
        page = person.new_page()
        page.goto(sketch.module.url)
        page.wait_for_function(
            f"document.getElementById('holder').textContent === {name + ' (you)'!r}",
            timeout=10000,
        )
        assert page.is_disabled("[data-testid=take]") and page.is_enabled("[data-testid=release]")
        # a second person watches the sketch page: sees the holder, cannot play
        watcher = browser.new_page(viewport={"width": 1400, "height": 900})
        watcher.goto(sketch.module.url)
        watcher.wait_for_function(
            f"document.getElementById('holder').textContent === {name!r}", timeout=10000
        )
        assert watcher.is_disabled("[data-testid=take]")
        watcher.click("[data-testid=play]")
        watcher.wait_for_function(
            "document.getElementById('notice').textContent.length > 0", timeout=10000
        )
        assert watcher.inner_text("[data-testid=notice]") == (
            f"refused vcr play: {name} holds control"
        )
        assert watcher.get_attribute("[data-testid=notice]", "class") == "error"
        for p in (page, watcher):  # counted, and shown on every page
            p.wait_for_function(
                "document.getElementById('refused').textContent === '1 refused'", timeout=10000
            )
        time.sleep(0.3)  # a window: the refused play sends nothing
        assert stepper.commands(sketch) == []
        # the holder plays from the sketch page
        page.click("[data-testid=play]")
        wait_for(lambda: stepper.commands(sketch) == ["vcr play"], 5.0, "play")
        page.wait_for_function(
            "document.getElementById('notice').textContent === 'sent vcr play'", timeout=10000
        )
        # released on the console: the watcher takes control on the sketch page; now the
        # first person is the one refused, on both pages
        desk.click("#release")
        watcher.wait_for_function(
            "document.getElementById('holder').textContent === 'nobody'", timeout=10000
        )
        watcher.click("[data-testid=take]")
        watcher.wait_for_function(
            "document.getElementById('holder').textContent.endsWith(' (you)')", timeout=10000
        )
        you = watcher.inner_text("[data-testid=holder]").removesuffix(" (you)")
        assert you.startswith("sketch viewer ")
        desk.wait_for_function(
            f"document.getElementById('holder').textContent === {you!r}", timeout=10000
        )
        page.click("[data-testid=pause]")
        page.wait_for_function(
            "document.getElementById('notice').textContent.includes('holds control')",
            timeout=10000,
        )
        watcher.click("[data-testid=pause]")
        wait_for(
            lambda: stepper.commands(sketch) == ["vcr play", "vcr pause"], 5.0, "play, then pause"
        )
        assert console.module.arbiter.refused == sketch.module.summary()["control_refused"] == 2
