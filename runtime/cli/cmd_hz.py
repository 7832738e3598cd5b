"""``umbra hz KEY``: the rate of one output of a running graph, as ``ros2 topic hz`` gives it."""

from __future__ import annotations

import argparse
import itertools
import statistics
import sys
import threading
import time
from collections import deque
from typing import TYPE_CHECKING

from umbra.connectors.cli_support import check_seconds
from umbra.connectors.errors import UserError
from umbra.runtime.cli.observing import (
    add_observer_args,
    full_key,
    open_observation,
    run_ended_text,
)

if TYPE_CHECKING:  # annotations only: `umbra --help` loads this file without them
    from umbra.runtime.links.observe import Observed

NAME = "hz"
HELP = "print the rate of an output of a running graph (KEY or MODULE/PORT) every second"
GUIDE = "docs/guide/recording.md"  # the guide page this command's --help points to


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("key", metavar="KEY", help="PREFIX/MODULE/PORT or MODULE/PORT")
    add_observer_args(parser)
    parser.add_argument(
        "--window", type=int, default=1000, metavar="N", help="samples averaged (default 1000)"
    )
    parser.add_argument(
        "--duration", type=float, metavar="S", help="stop after S seconds (default: run on)"
    )


def main(args: argparse.Namespace) -> int:
    if args.window < 2:
        raise UserError(f"--window must be at least 2 samples, found {args.window}")
    check_seconds("--duration", args.duration)
    observation = open_observation(args)
    arrivals: deque[float] = deque(maxlen=args.window)
    lock = threading.Lock()
    ended = threading.Event()

    fresh = [0]  # samples since the last line

    def on_sample(o: Observed) -> None:
        if o.kind == "end":
            ended.set()
        elif o.kind == "sample":
            with lock:
                arrivals.append(o.arrival)
                fresh[0] += 1

    try:
        key = full_key(observation, args.key)
        observation.subscribe(on_sample, key)
        start = time.monotonic()
        while args.duration is None or time.monotonic() - start < args.duration:
            time.sleep(1.0 if args.duration is None else min(1.0, args.duration))
            with lock:
                times, new = list(arrivals), fresh[0]
                fresh[0] = 0
            print(_line(key, times) if new else f"{key}: no new samples", flush=True)
            if ended.is_set():
                print(f"umbra hz: {key}: the producer ended the stream", file=sys.stderr)
                return 0
            if observation.ended.is_set():
                print(f"umbra hz: {run_ended_text(observation)}", file=sys.stderr)
                return 1
    finally:
        observation.close()
    return 0


def _line(key: str, times: list[float]) -> str:
    """``average rate: R Hz`` with the periods' min, max and (population) standard deviation
    [s], from the arrival times ``times`` [s]."""
    if len(times) < 2:
        return f"{key}: one sample so far"
    periods = [b - a for a, b in itertools.pairwise(times)]
    rate = 1.0 / statistics.fmean(periods)
    return (
        f"{key}: average rate: {rate:.3f} Hz\n"
        f"\tmin: {min(periods):.4f} s max: {max(periods):.4f} s "
        f"std dev: {statistics.pstdev(periods):.5f} s window: {len(times)}"
    )
