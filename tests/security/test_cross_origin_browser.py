"""A real cross-origin page in Chromium tries to drive the console while the operator's page,
open in the same browser, holds control: the attacker's page is served from another loopback
port (same site for the browser, so the SameSite cookie goes along; another origin, so the
server's Origin check is what stops it). It opens the console's socket, posts commands with
fetch and with a form, and reads what it can; it gets nothing, and the console never sees it."""

from __future__ import annotations

import http.server
import threading
from collections.abc import Iterator
from contextlib import contextmanager

import pytest

from tests.operator.browser import chromium, needs_chromium, take_control
from tests.operator.helpers import image
from tests.security.console_rig import console_rig

pytestmark = [pytest.mark.browser, needs_chromium]

ATTACK = """<!doctype html><title>totally unrelated page</title><script>
window.results = {};
const target = "http://127.0.0.1:%(port)d";
function socket(url) {
  return new Promise(done => {
    const ws = new WebSocket(url);
    ws.onopen = () => { ws.send(JSON.stringify({type: "take", seq: 1, session: "x"}));
                        done("open"); };
    ws.onerror = () => done("error");
    ws.onclose = e => done("closed " + e.code);
    setTimeout(() => done("timeout"), 5000);
  });
}
async function attack() {
  results.ws = await socket("ws://127.0.0.1:%(port)d/ws");
  results.ws_token = await socket("ws://127.0.0.1:%(port)d/ws?token=guess-guess-guess-guess");
  try {
    const r = await fetch(target + "/sketch/control", {method: "POST", mode: "no-cors",
      credentials: "include", body: JSON.stringify({action: "take"})});
    results.post = "sent " + r.type;
  } catch (e) { results.post = "failed " + e; }
  try {
    const r = await fetch(target + "/", {credentials: "include"});
    results.read = "read " + (await r.text()).slice(0, 40);
  } catch (e) { results.read = "failed"; }
  const form = document.createElement("form");
  form.method = "POST"; form.action = target + "/sketch/command"; form.target = "sink";
  form.enctype = "text/plain";
  const input = document.createElement("input");
  input.name = '{"text": "vcr play", "x": "'; input.value = '"}';
  form.appendChild(input); document.body.appendChild(form);
  const sink = document.createElement("iframe"); sink.name = "sink";
  document.body.appendChild(sink);
  form.submit();
  await new Promise(r => setTimeout(r, 1000));
  results.done = true;
}
attack();
</script>"""


@contextmanager
def _attacker(port: int) -> Iterator[str]:
    """The attacker's page on another loopback port."""
    body = (ATTACK % {"port": port}).encode()

    class Handler(http.server.BaseHTTPRequestHandler):
        def do_GET(self) -> None:
            self.send_response(200)
            self.send_header("content-type", "text/html")
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, *args: object) -> None:
            pass

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}/"
    finally:
        server.shutdown()
        server.server_close()


def test_a_cross_origin_page_cannot_drive_the_console() -> None:
    with console_rig() as rig, chromium() as browser:
        m = rig.h.module
        with rig.lock:
            rig.h.push("image", image())
        context = browser.new_context()
        operator = context.new_page()
        operator.goto(m.url)
        operator.wait_for_function("window.umbra && window.umbra.state", timeout=20000)
        take_control(operator)
        assert "token=" not in operator.url  # the address lost its token
        holder = m.arbiter.holder
        with _attacker(m._server.port) as evil_url:
            evil = context.new_page()  # a tab of the operator's browser
            evil.goto(evil_url)
            evil.wait_for_function("window.results && window.results.done", timeout=20000)
            results = evil.evaluate("window.results")
        assert results["ws"] in ("error", "closed 1006"), results
        assert results["ws_token"] in ("error", "closed 1006"), results
        assert results["post"] == "sent opaque", results  # sent, unreadable...
        assert results["read"] == "failed", results  # ...and nothing read back
        refusals = m._server.gate.refusals.counts
        assert refusals["origin"] >= 4, dict(refusals)  # 2 sockets, 1 read, 2 posts at least
        # the console never saw the attacker: one page, the operator's, holding control
        assert list(m.arbiter.sessions) == [holder] and m.arbiter.holder == holder
        assert m.counts["refused"] == 0
