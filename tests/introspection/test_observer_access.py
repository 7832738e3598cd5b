"""An observer reads and cannot write; a stranger cannot even read. Real processes under the
launcher, with their per-run credentials and the rules derived from the graph."""

from __future__ import annotations

import json
import signal
import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import zenoh

from tests.introspection.helpers import running, user_folder
from tests.links.conftest import Running, guarded_arm_graph
from tests.poll import wait_for
from umbra.connectors.codec import Codec
from umbra.connectors.messages import Twist
from umbra.runtime.links.config import Endpoints, build_config
from umbra.runtime.links.observe import Observation, Observed
from umbra.runtime.links.runs import observer_endpoint

# whole runs of umbra in subprocesses, seconds each: in CI with -m slow (a short default run)
pytestmark = pytest.mark.slow

KEY = "umbra/observed/source/twist"


def test_an_observer_reads_but_its_commands_never_arrive_and_strangers_read_nothing(
    umbra: Callable[..., Running], plugin_env: dict[str, str], tmp_path: Path
) -> None:
    (tmp_path / "g.yaml").write_text(guarded_arm_graph("observed"))
    run = umbra("run", "g.yaml", "--duration", "300", "--out", "out", "--quiet")
    graph = running(run, plugin_env)
    endpoints = sorted(observer_endpoint(e) for p in graph.processes for e in p.listen)
    seen: list[Observed] = []
    observer = Observation.open(folder=user_folder(plugin_env))
    guessing = build_config(Endpoints(connect=endpoints))
    guessing.insert_json5(
        "transport/auth/usrpwd", json.dumps({"user": "observer@umbra", "password": "guess"})
    )
    strangers = [
        zenoh.open(build_config(Endpoints(connect=endpoints))),  # no credentials at all
        zenoh.open(guessing),  # the observer's user name, a wrong password
    ]
    overheard: list[zenoh.Sample] = []
    lock = threading.Lock()

    def overhear(sample: zenoh.Sample) -> None:
        with lock:
            overheard.append(sample)

    try:
        for stranger in strangers:
            stranger.declare_subscriber(KEY, overhear)
        twists: list[zenoh.Sample] = []
        observer.subscribe(seen.append, KEY)
        raw = observer.session.declare_subscriber(KEY, twists.append)
        # the observer reads
        wait_for(
            lambda: len(seen) >= 20 and len(twists) >= 20, 10.0, "20 samples and 20 twists read"
        )
        assert all(o.kind == "sample" and o.type_name == "Twist" for o in seen[:20])
        source = twists[-1].source_info
        raw.undeclare()
        codec = Codec()
        pub = observer.session.declare_publisher(
            KEY, congestion_control=zenoh.CongestionControl.BLOCK
        )
        forged = Twist(vector=np.array([0.05, 0, 0, 0, 0, 0.3]), frame="camera", seq=2**40)
        for _ in range(25):
            pub.put(codec.encode(forged), source_info=None)  # as itself
            pub.put(codec.encode(forged), source_info=source)  # in the producer's name
            time.sleep(0.02)
        time.sleep(0.3)  # a window: the forged commands reach nobody
        for stranger in strangers:  # refused when they opened their session
            assert list(stranger.info.transports()) == []
        with lock:
            assert overheard == []
    finally:
        observer.close()
        for stranger in strangers:
            stranger.close()
    run.popen.send_signal(signal.SIGINT)
    assert run.finish() == 130, run.text
    summary = json.loads((tmp_path / "out" / "summary-smart.json").read_text())
    (sub,) = [s for s in summary["links"]["subscribe"] if s["key"] == KEY]
    assert sub["received"] > 20
    # nothing of the observer's reached the consumer: not one sample to refuse
    assert (sub["foreign"], sub["implausible"], sub["stale_dropped"]) == (0, 0, 0), sub
    arm = next(m for m in summary["modules"] if m["module"] == "arm")
    assert arm["moved_rad"] < 1e-9
