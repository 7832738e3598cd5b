"""The viser 3-D view behind the same door as the operator's pages: its page and its websocket
need the per-run token (real viser server, real HTTP and websocket clients)."""

from __future__ import annotations

import json
from pathlib import Path

import httpx
import pytest
from websockets.exceptions import InvalidStatus
from websockets.sync.client import connect

from tests.view3d.test_view3d_module import FRAMES
from umbra.modules.view3d.view3d import View3D
from umbra.runtime.harness import ModuleHarness

TOKEN = "a-token-of-this-run-0123456789"


def test_the_3d_view_refuses_requests_and_sockets_without_the_token(tmp_path: Path) -> None:
    token_file = tmp_path / "token"
    token_file.write_text(TOKEN + "\n")
    params = {"port": 0, "token_file": str(token_file)}
    with ModuleHarness(View3D, params, frames=FRAMES, output_dir=tmp_path) as h:
        address = h.module.address
        base = address.split("?")[0]
        port = int(base.rsplit(":", 1)[1].strip("/"))
        assert address == f"{base}?token={TOKEN}"
        # no token, a wrong one: no page, no socket
        for url in (base, f"{base}?token=wrong-{TOKEN}", f"{base}index.html"):
            answer = httpx.get(url)
            assert answer.status_code == 403, (url, answer.status_code)
            assert "access token" in answer.text
        for ws in (f"ws://127.0.0.1:{port}/", f"ws://127.0.0.1:{port}/?token=wrong"):
            with pytest.raises(InvalidStatus) as refused:
                connect(ws, open_timeout=5, subprotocols=["viser-v1"]).close()
            assert refused.value.response.status_code == 403
        # another site's page and a DNS-rebinding Host: refused even with the token
        cookie = {f"umbra_token_{port}": TOKEN}
        evil = httpx.get(base, cookies=cookie, headers={"Origin": "http://evil.example"})
        assert evil.status_code == 403
        rebound = httpx.get(base, cookies=cookie, headers={"Host": f"evil.example:{port}"})
        assert rebound.status_code == 421
        # the address: the token traded for a cookie named for this port, then the page
        with httpx.Client() as browser:
            first = browser.get(address)
            assert first.status_code == 303 and first.headers["location"] == "/"
            assert browser.cookies.get(f"umbra_token_{port}") == TOKEN
            page = browser.get(base)
            assert page.status_code == 200 and "<html" in page.text.lower()
        with connect(
            f"ws://127.0.0.1:{port}/",
            open_timeout=5,
            subprotocols=["viser-v1"],
            additional_headers={"Cookie": f"umbra_token_{port}={TOKEN}"},
        ) as socket:
            assert socket.subprotocol is not None  # viser took the socket
        summary = h.module.summary()
        assert summary["refused_requests"] >= 7
        assert TOKEN not in json.dumps(summary)  # summaries are files


class _RaisesOnEveryAttribute:
    """Like canopen's placeholder network: any attribute, ``__class__`` too, raises."""

    def __getattribute__(self, name: str) -> object:
        raise RuntimeError("no attribute of me may be read")


def test_the_door_is_put_up_beside_objects_that_raise_on_any_attribute(tmp_path: Path) -> None:
    # the door finds viser's server among the live objects; one that refuses to say its class
    # (canopen's, after any canopen test in the same worker) once broke the 3-D view's start
    hostile = [_RaisesOnEveryAttribute() for _ in range(3)]
    with ModuleHarness(View3D, {"port": 0}, frames=FRAMES, output_dir=tmp_path) as h:
        base = h.module.address.split("?")[0]
        assert httpx.get(base).status_code == 403
    assert len(hostile) == 3
