"""OperatorConsole in the harness with its real web server and a real websocket client."""

from __future__ import annotations

import json
import time
from pathlib import Path

import httpx
import numpy as np
import pytest
from websockets.exceptions import InvalidStatus

from tests.operator.helpers import Page, client, image, rectangle_contour
from umbra.connectors.commands import GrabAction, Seed, SeedShape
from umbra.connectors.errors import UserError
from umbra.connectors.states import ServoReason, ServoStage, ServoState
from umbra.connectors.tracking import SnakeCheck
from umbra.modules.operator.console import OperatorConsole
from umbra.modules.operator.jog import JogStop
from umbra.runtime.harness import ModuleHarness

T_TOOL_CAMERA = np.eye(4)
T_TOOL_CAMERA[:3, 3] = [0.0, 0.0, -0.12]


def _harness(**params: object) -> ModuleHarness:
    return ModuleHarness(OperatorConsole, params, frames={"tool->camera": T_TOOL_CAMERA})


def _pump(h: ModuleHarness, until, timeout: float = 5.0, dt: float = 0.005) -> None:
    """Step the console (a fresh image each step) until ``until()`` or fail."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        h.push("image", image())
        h.step(dt=dt)
        if until():
            return
        time.sleep(0.005)
    raise AssertionError("condition not reached in time")


def _state(h: ModuleHarness, page: Page, pred, timeout: float = 5.0) -> dict:
    """The first state the page receives that satisfies ``pred`` (stepping the console)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        _pump(h, lambda: True)
        try:
            state = page.recv_text("state", timeout=0.1)
        except TimeoutError:
            continue
        if pred(state):
            return state
    raise AssertionError("no such state in time")


def _operator(h: ModuleHarness) -> Page:
    """A page connected to the console that has taken control."""
    page = Page(h.module.url)
    try:
        _pump(h, lambda: page.session in h.module.arbiter.sessions)
        page.send("take")
        _pump(h, lambda: h.module.arbiter.holder == page.session)
    except BaseException:
        page.close()
        raise
    return page


def _frame_seq(h: ModuleHarness) -> int:
    return h.module.image.value.seq


def test_without_a_page_the_simulated_operators_seed_passes_until_a_person_acts() -> None:
    with _harness(serve=False) as h:
        h.push("image", image())
        h.push("sim_seed", Seed.point(340.0, 230.0))
        out = h.step(dt=0.02)
        assert out["seed"][0].uv.tolist() == [340.0, 230.0]
        assert out["seed"][0].shape == SeedShape.POINT
        presence = h.output("presence")
        assert not presence.person and not presence.acted and presence.holder == ""
        h.module.arbiter.join("s1", "viewer")
        assert h.module.arbiter.take("s1").ok
        h.push("sim_seed", Seed.point(10.0, 10.0))
        out = h.step(dt=0.02)
        assert "seed" not in out or not out["seed"]
        presence = h.output("presence")
        assert presence.person and presence.acted and presence.holder == "viewer"
        assert h.module.summary()["sim_seeds_ignored"] == 1


def test_click_from_the_holder_seeds_and_a_viewer_without_control_is_refused() -> None:
    with _harness() as h:
        url = h.module.url
        assert url.startswith("http://127.0.0.1:")
        h.push("image", image())
        h.step(dt=0.02)
        operator, viewer = Page(url), Page(url)
        try:
            _pump(h, lambda: len(h.module.arbiter.sessions) == 2)
            seq = _frame_seq(h)
            viewer.send("click", u=340.0, v=230.0, frame=seq)  # no control yet: refused
            operator.send("take")
            _pump(h, lambda: h.module.arbiter.holder == operator.session)
            viewer.send("take")  # a second operator: refused
            seq = _frame_seq(h)
            operator.send("click", u=341.5, v=229.0, frame=seq)
            _pump(h, lambda: h.module.counts["seeds"] == 1)
            assert h.output("seed").uv.tolist() == [341.5, 229.0]
            assert h.module.counts["refused"] == 2
            assert h.module.arbiter.refused == 2
            # every page is told who holds control
            state = _state(
                h, viewer, lambda s: s["control"] == operator.name and len(s["notices"]) >= 6
            )
            texts = [n["text"] for n in state["notices"] if n["to"] == viewer.session]
            assert any("take control first" in t for t in texts)
            assert any("holds control" in t for t in texts)
            presence = h.output("presence")
            assert presence.person and presence.holder == operator.name and presence.viewers == 2
        finally:
            operator.close()
            viewer.close()


def test_clicks_outside_the_image_and_on_a_stale_page_are_refused_with_the_reason() -> None:
    with _harness(stale_page_s=1.0) as h:
        page = _operator(h)
        try:
            old = _frame_seq(h)
            page.send("click", u=700.0, v=20.0, frame=old)
            _pump(h, lambda: h.module.counts["refused"] == 1)
            for _ in range(60):  # 1.2 s of run time: the old frame is stale now
                h.push("image", image())
                h.step(dt=0.02)
            page.send("click", u=340.0, v=230.0, frame=old)
            _pump(h, lambda: h.module.counts["refused"] == 2)
            texts = [n["text"] for n in map(vars, h.module.board.lines) if n["level"] == "error"]
            assert "click outside the image: expected 0 <= u < 640" in texts[0]
            assert texts[1].startswith("stale page: the image you acted on is 1.")
            assert texts[1].endswith("expected at most 1.000 s")
            assert h.module.counts["seeds"] == 0
        finally:
            page.close()


def test_nobody_jogs_on_a_frozen_page_but_a_live_one_jogs_and_a_release_always_goes() -> None:
    """A held jog names the frame the page shows; a page whose video froze (that frame older
    than ``stale_page_s``) is refused and nothing moves, while its release still passes."""
    with _harness(stale_page_s=0.5) as h:
        page = _operator(h)
        try:
            old = _frame_seq(h)
            for _ in range(40):  # 0.8 s of run time: the page still shows `old`
                h.push("image", image())
                h.step(dt=0.02)
            page.send("jog", held=True, axes=[1, 0, 0, 0], jog_frame="camera", speed=1.0, frame=old)
            _pump(h, lambda: h.module.counts["refused"] == 1)
            texts = [n["text"] for n in map(vars, h.module.board.lines) if n["level"] == "error"]
            assert texts[-1].startswith("jog refused: stale page: the image you acted on is 0.")
            assert not any(np.any(t.vector) for t in h.outputs("jog"))
            live = _frame_seq(h)  # the same hold on a live picture stays stopped (no bursts)
            page.send(
                "jog", held=True, axes=[1, 0, 0, 0], jog_frame="camera", speed=1.0, frame=live
            )
            for _ in range(20):  # the keep-alive is handled, and ignored
                h.push("image", image())
                h.step(dt=0.005)
                time.sleep(0.005)
            stopped = h.module.view.state(h.now)["jog_stopped"]
            assert stopped["code"] == JogStop.STALE_PICTURE, stopped
            assert not any(np.any(t.vector) for t in h.outputs("jog"))
            page.send(  # released, then pressed again on the live picture: it jogs
                "jog", held=False, axes=[0, 0, 0, 0], jog_frame="camera", speed=1.0, frame=live
            )
            page.send(
                "jog", held=True, axes=[1, 0, 0, 0], jog_frame="camera", speed=1.0, frame=live
            )
            _pump(h, lambda: any(np.any(t.vector) for t in h.outputs("jog")))
            page.send(
                "jog", held=False, axes=[0, 0, 0, 0], jog_frame="camera", speed=1.0, frame=old
            )
            _pump(h, lambda: not np.any(h.outputs("jog")[-1].vector))
            assert h.module.counts["refused"] == 1  # the release on the old frame went through
        finally:
            page.close()


def test_malformed_and_replayed_messages_are_refused_and_counted(
    caplog: pytest.LogCaptureFixture,
) -> None:
    with _harness() as h:
        page = _operator(h)
        try:
            page.raw("{not json")
            assert "expected JSON" in page.recv_text("notice")["text"]
            replay = json.dumps({"session": page.session, "seq": 1, "type": "take"})
            page.raw(replay)
            assert "replayed message: expected seq > 1, found 1" in page.recv_text("notice")["text"]
            other = json.dumps({"session": "0123456789abcdef", "seq": 99, "type": "take"})
            page.raw(other)
            assert (
                "replayed message: expected this page's session" in page.recv_text("notice")["text"]
            )
            page.send("click", u=float("nan"), v=1.0, frame=1)  # NaN is not valid JSON number
            assert "malformed" in page.recv_text("notice")["text"]
            page.send("jog", held=True, axes=[5, 0, 0, 0], jog_frame="tool", speed=1.0)
            assert "4 numbers in [-1, 1]" in page.recv_text("notice")["text"]
            page.ws.send(b"\x00\x01binary")
            assert "expected JSON" in page.recv_text("notice")["text"]
            _pump(h, lambda: h.module.summary()["bad_messages"] == 6)
            s = h.module.summary()
            assert (s["malformed"], s["replayed"]) == (4, 2)
            assert not h.outputs("jog")
            # the page was told at once, by the web side; nothing was queued for the module,
            # and no log line per message (a flood of junk is not a flood of log lines)
            texts = [n["text"] for n in map(vars, h.module.board.lines)]
            assert not any(t.startswith(("malformed", "replayed")) for t in texts), texts
            assert "replayed message" not in caplog.text and "malformed" not in caplog.text
            assert s["closed_abusers"] == 0  # 6 is under the limit: the page stays
            page.send("action", action="abort")
            _pump(h, lambda: h.module.counts["abort"] == 1)
        finally:
            page.close()


def test_another_sites_page_cannot_open_the_socket() -> None:
    with _harness() as h:
        port = h.module.url.split(":")[2].rstrip("/")
        with pytest.raises(InvalidStatus, match="HTTP 403"):
            Page(h.module.url, origin="http://evil.example")
        Page(h.module.url, origin=f"http://127.0.0.1:{port}").close()  # its own page
        assert h.module.summary()["refused_requests"] == 1


def test_resume_is_refused_while_the_snake_is_not_healthy() -> None:
    with _harness() as h:
        page = _operator(h)
        try:
            h.push("contour", rectangle_contour("failed", "contour touches the image border"))
            page.send("action", action="resume")
            _pump(h, lambda: h.module.counts["refused"] == 1)
            assert not h.outputs("operator")
            text = h.module.board.lines[-1].text
            assert (
                "resume refused: the snake is not healthy (contour touches the image border)"
                in text
            )
            h.push("contour", rectangle_contour())
            page.send("action", action="resume")
            _pump(h, lambda: h.module.counts["resume"] == 1)
            assert h.output("operator").action == GrabAction.RESUME
            page.send("action", action="abort")
            _pump(h, lambda: h.module.counts["abort"] == 1)
            assert h.output("operator").action == GrabAction.ABORT
        finally:
            page.close()


def test_assistance_request_keeps_the_frame_and_reason_for_the_dialog() -> None:
    with _harness() as h:
        page = Page(h.module.url)
        try:
            h.push("contour", rectangle_contour("failed", "area changed too fast"))
            assist = ServoState(
                stage=ServoStage.ASSIST,
                assist=True,
                reason="snake failure: area",
                code=ServoReason.SNAKE_FAILED,
                checks=(SnakeCheck.AREA_CHANGE,),
            )
            h.push("servo", assist)
            _pump(h, lambda: h.module._assist is not None)
            state = _state(h, page, lambda s: s["assist"] is not None)
            assert state["assist"]["reason"] == "snake failure: area"
            assert state["assist"]["plain"] == "the patch's size jumped"
            assert state["assist"]["overlay"]["status"] == "failed"
            assert "vsServo asks for the operator" in state["banner"]
            http, base = client(h.module.url)
            jpeg = http.get(base + "/assist.jpg")
            assert jpeg.status_code == 200 and jpeg.content[:2] == b"\xff\xd8"
        finally:
            page.close()


def test_the_token_is_needed_on_loopback_too(tmp_path: Path) -> None:
    token_file = tmp_path / "token"
    token_file.write_text("s3cret-token-for-tests\n")
    with _harness(token_file=str(token_file)) as h:
        base = h.module.url.split("?")[0]
        assert base.startswith("http://127.0.0.1:")
        assert h.module.url.endswith("?token=s3cret-token-for-tests")
        refused = httpx.get(base, timeout=5)
        assert refused.status_code == 403 and b"access token" in refused.content
        wrong = httpx.get(base + "?token=guess-guess-guess-guess", timeout=5)
        assert wrong.status_code == 403
        # the address's token is exchanged for a cookie, and the address loses it
        swap = httpx.get(h.module.url, timeout=5)
        assert swap.status_code == 303 and swap.headers["location"] == "/"
        cookie = swap.headers["set-cookie"]
        assert cookie.startswith("umbra_token=s3cret-token-for-tests;")
        assert "HttpOnly" in cookie and "SameSite=Strict" in cookie
        ok = httpx.get(base, cookies={"umbra_token": "s3cret-token-for-tests"}, timeout=5)
        assert ok.status_code == 200 and "umbra operator station" in ok.text
        with pytest.raises(InvalidStatus, match="HTTP 403"):
            Page(base)
        Page(h.module.url).close()
        assert h.module.summary()["refused_requests"] == 3
    assert h.module.summary()["refused_requests"] == 3  # still there once the server stopped


def test_listening_beyond_loopback_without_a_token_file_makes_one(
    caplog: pytest.LogCaptureFixture,
) -> None:
    import logging
    import socket

    caplog.set_level(logging.INFO)
    with _harness(host="0.0.0.0") as h:
        token = h.module.url.split("?token=")[1]
        assert len(token) >= 20
        port = h.module._server.port
        assert httpx.get(f"http://127.0.0.1:{port}/", timeout=5).status_code == 403
        # printed at start, with this machine's name for the operator's computer
        assert f"operator console: http://127.0.0.1:{port}/?token={token}" in caplog.text
        assert f"open http://{socket.gethostname()}:{port}/?token={token}" in caplog.text


def test_a_short_token_file_is_a_user_error(tmp_path: Path) -> None:
    (tmp_path / "t").write_text("short\n")
    with (
        pytest.raises(
            UserError, match="at least 16 printable ASCII characters, found 5 characters"
        ),
        _harness(token_file=str(tmp_path / "t")),
    ):
        pass


def test_another_module_serves_its_page_on_the_consoles_server() -> None:
    from fastapi.responses import HTMLResponse

    from umbra.modules.operator.web_server import acquire_server, release_server

    async def sketch() -> HTMLResponse:
        return HTMLResponse("<h1>sketch</h1>")

    with _harness() as h:
        server = acquire_server(h.module.context)  # what a second module of the process does
        try:
            assert server is h.module._server
            server.app.add_api_route("/sketch", sketch, methods=["GET"])
            server.add_link("/sketch", "Active Sketch")
            http, base = client(h.module.url)
            reply = http.get(base + "/sketch")
            assert reply.status_code == 200 and reply.text == "<h1>sketch</h1>"
            page = Page(h.module.url)
            try:
                state = _state(h, page, lambda s: bool(s["links_extra"]))
                assert state["links_extra"] == {"/sketch": "Active Sketch"}
            finally:
                page.close()
            with pytest.raises(UserError, match=r"already serves on 127\.0\.0\.1"):
                acquire_server(h.module.context, port=1)
        finally:
            release_server(server)
        assert http.get(base + "/").status_code == 200  # still the console's


def test_zoom_sliders_drive_the_cameras_and_the_scripted_zoom_steps_aside() -> None:
    from umbra.connectors.messages import Scalar

    with _harness(zoom_names=["left", "right"]) as h:
        h.push("zoom_auto", Scalar(value=0.2))
        out = h.step(dt=0.01)
        assert out["zoom_1"][0].value == 0.2 and out["zoom_2"][0].value == 0.2
        page = Page(h.module.url)
        try:
            _pump(h, lambda: page.session in h.module.arbiter.sessions)
            page.send("take")
            page.send("zoom", camera="left", value=0.7)
            page.send("zoom", camera="middle", value=0.5)
            _pump(h, lambda: h.module.counts["refused"] == 1)
            assert h.output("zoom_1").value == 0.7
            h.push("zoom_auto", Scalar(value=0.3))  # a person zoomed: the script steps aside
            h.step(dt=0.01)
            assert h.output("zoom_1").value == 0.7 and h.output("zoom_2").value == 0.2
            assert "expected a camera of ['left', 'right'], found 'middle'" in (
                h.module.board.lines[-1].text
            )
        finally:
            page.close()


def test_the_page_shows_how_old_each_links_latest_sample_got() -> None:
    with _harness(state_rate_hz=12.8) as h:  # a page update every 5/64 s
        page = Page(h.module.url)
        try:
            _pump(h, lambda: page.session in h.module.arbiter.sessions)
            h.push("contour", rectangle_contour())
            seen: list[dict] = []
            version = h.module._app.state.get()[0]
            for k in range(64):  # steps of 1/64 s, an image every 4th: 4/64 s apart
                if k % 4 == 0:
                    h.push("image", image())
                h.step(dt=1 / 64)
                if h.module._app.state.get()[0] > version:
                    version, state = h.module._app.state.get()
                    seen.append({link["name"]: link["age_ms"] for link in state["links"]})
            assert len(seen) >= 10
            # at any one step the image is 1/64 .. 4/64 s old; each update shows the oldest
            # it got since the one before (5 steps: a whole period of the image)
            assert {ages["image"] for ages in seen[1:]} == {62.5}, seen
            contour = [ages["contour"] for ages in seen]
            assert contour == sorted(contour) and contour[-1] >= 900.0  # no contour since
            assert seen[-1]["servo"] is None and seen[-1]["joints"] is None  # nothing came
            # a busy process runs the console only in the ticks that bring an image: its age
            # is 0 at every step, yet each image was 4/64 s old when the next one came
            images = []
            for _ in range(16):
                h.clock.wait_until(h.now + 4 / 64)
                h.push("image", image())
                h.step(dt=0.0)
                if h.module._app.state.get()[0] > version:
                    version, state = h.module._app.state.get()
                    images.append(state["links"][0]["age_ms"])
            assert len(images) >= 4 and set(images[1:]) == {62.5}, images
        finally:
            page.close()
