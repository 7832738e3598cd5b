"""Abort and pause always win: floods of junk, of large messages and of connections against the
console's real web server while a test operator holding control aborts (each flood its own
process). Every abort must land within a second, and their median within 150 ms of being sent
and within 150 ms of the median under the same CPU load from outside (the ``burn`` process: busy
threads, no connection) in the same run. A holder's page closed mid-flood gives
control back; no ghost viewer is left once the floods stop.

Load needed: these tests time the abort, so they compare each flood with the same run's case
without one (on this 2-core machine shared by several jobs, a flood's own process costs the
server CPU before it sends a byte)."""

from __future__ import annotations

import json
import statistics
import time

import pytest

from tests.operator.helpers import Page
from tests.security.console_rig import console_rig, flood

ABORTS = 8
BOUND_S = 0.150


def _aborts(rig, page: Page) -> list[float]:
    out = []
    for _ in range(ABORTS):
        out.append(rig.abort_latency(page))
        time.sleep(0.05)
    return out


@pytest.mark.slow
@pytest.mark.heavy
def test_the_holders_abort_lands_under_every_flood() -> None:
    with console_rig() as rig:
        page = rig.operator()
        try:
            figures = {"none": _aborts(rig, page)}
            for kind in ("burn", "junk", "big", "connections"):
                with flood(kind, rig.h.module.url, 3.0) as proc:
                    figures[kind] = _aborts(rig, page)
                report = json.loads(proc.stdout.read().strip().splitlines()[-1])
                # it did flood (1 MiB messages: each costs its sender a new socket)
                assert report["sent"] > {"burn": 0, "big": 10}.get(kind, 100), report
                if kind in ("junk", "big"):
                    assert report["closed"] >= 1, report  # and the server closed its sockets
            print({k: [round(x * 1e3, 1) for x in v] for k, v in figures.items()})
            base = statistics.median(figures["burn"])
            for kind in ("junk", "big", "connections"):
                lat = figures[kind]
                # the typical abort within 150 ms, and within 150 ms of the same CPU load from
                # outside; every one within a second (this 2-core machine, shared by several
                # jobs, preempts a process for 0.1-0.3 s now and then: single aborts that long
                # were seen under the 1 MiB flood and the junk flood, and are printed above)
                assert statistics.median(lat) <= min(BOUND_S, base + BOUND_S), (kind, lat, base)
                assert max(lat) < 1.0, (kind, lat)
            s = rig.h.module.summary()
            assert s["closed_abusers"] >= 1 and rig.h.module.counts["abort"] == 5 * ABORTS
            # no ghost viewers once the floods stopped: the operator's page alone
            rig.wait(
                lambda: list(rig.h.module.arbiter.sessions) == [page.session], 10, "one session"
            )
            assert rig.h.module._app.stats.viewers == 1
            assert rig.h.module.arbiter.holder == page.session
        finally:
            page.close()


@pytest.mark.slow
@pytest.mark.heavy
def test_a_holders_page_closed_mid_flood_gives_control_back() -> None:
    with console_rig() as rig:
        page = rig.operator()
        with flood("junk", rig.h.module.url, 4.0):
            page.close()
            rig.wait(lambda: rig.h.module.arbiter.holder is None, 2.0, "control released")
            # another operator takes control during the flood, and aborts
            second = rig.operator()
            try:
                assert rig.abort_latency(second) <= 1.0
            finally:
                second.close()
        rig.wait(lambda: not rig.h.module.arbiter.sessions, 10, "no session")
        assert rig.h.module._app.stats.viewers == 0
