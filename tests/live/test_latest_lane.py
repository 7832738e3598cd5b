"""The live server's lanes: the newest sample of each topic, every topic in its turn, however
busy the others (a real LatestLane between a producing and a starved consuming thread)."""

from __future__ import annotations

import itertools
import threading
import time

from umbra.runtime.live.latest_lane import CLOSED, LatestLane


def test_a_newer_sample_replaces_the_waiting_one_and_keeps_its_turn() -> None:
    lane = LatestLane()
    assert lane.put("/camera/image", 1) and lane.put("/joints/joint_state", 10)
    assert not lane.put("/camera/image", 2)  # replaced: a drop
    assert len(lane) == 2
    assert lane.get(0.1) == 2  # the image's turn came first; its newest sample
    assert lane.get(0.1) == 10
    assert lane.get(0.01) is None
    lane.close()
    assert lane.get(1.0) is CLOSED


def test_a_starved_consumer_still_gets_every_topic_beside_a_flood() -> None:
    """Ten topics at full speed from one thread, one slow topic beside them: the consumer, far
    slower than the producers, gets samples of every topic (a drop-the-newest queue let the
    fast ones fill it and the slow one through only by luck)."""
    lane = LatestLane()
    stop = threading.Event()

    def flood() -> None:
        n = 0
        while not stop.is_set():
            for k in range(10):
                lane.put(f"/busy/{k}", ("busy", k, n))
            n += 1

    def slow() -> None:
        n = 0
        while not stop.is_set():
            lane.put("/joints/joint_state", ("joints", 0, n))
            n += 1
            time.sleep(0.01)

    threads = [threading.Thread(target=flood), threading.Thread(target=slow)]
    for t in threads:
        t.start()
    got: dict[str, list[int]] = {}
    try:
        end = time.monotonic() + 1.0
        while time.monotonic() < end:
            item = lane.get(0.1)
            if item is not None:
                name, k, n = item
                got.setdefault(f"{name}{k}", []).append(n)
            time.sleep(0.002)  # a consumer starved of CPU
    finally:
        stop.set()
        for t in threads:
            t.join()
    assert len(got) == 11, sorted(got)
    assert len(got["joints0"]) >= 5, got["joints0"]
    assert all(b > a for a, b in itertools.pairwise(got["joints0"]))  # in order, newest
    assert len(lane) <= 11  # bounded by the topics
