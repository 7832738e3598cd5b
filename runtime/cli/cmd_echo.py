"""``umbra echo KEY``: print the samples of one output of a running graph, decoded."""

from __future__ import annotations

import argparse
import queue
import sys
import time
from typing import TYPE_CHECKING

from umbra.connectors.cli_support import check_seconds
from umbra.connectors.json_text import json_text
from umbra.runtime.cli.observing import (
    add_observer_args,
    full_key,
    message_fields,
    open_observation,
    run_ended_text,
)
from umbra.runtime.ros2 import shell as ros2_shell
from umbra.runtime.ros2.run_args import wants_ros2

if TYPE_CHECKING:  # annotations only: `umbra --help` loads this file without them
    from umbra.runtime.links.observe import Observed

NAME = "echo"
HELP = "print the samples of an output of a running graph (KEY or MODULE/PORT), decoded"
GUIDE = "docs/guide/recording.md"  # the guide page this command's --help points to


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "key", metavar="KEY", help="PREFIX/MODULE/PORT or MODULE/PORT; a ROS 2 /topic with --ros2"
    )
    add_observer_args(parser)
    parser.add_argument("--once", action="store_true", help="print one sample and exit")
    parser.add_argument("--json", action="store_true", help="one JSON object per sample")
    parser.add_argument(
        "--timeout",
        type=float,
        metavar="S",
        help="exit 1 when no sample came for S seconds (default: wait)",
    )
    ros2_shell.add_shell_args(parser)  # KEY a ROS 2 topic (`/joint_states`)


#: Seconds between two looks at whether the run has ended while no sample comes.
LOOK_PERIOD = 0.2


def main(args: argparse.Namespace) -> int:
    check_seconds("--timeout", args.timeout)
    if wants_ros2(args):
        return ros2_shell.echo(args, args.key)
    observation = open_observation(args)
    try:
        key = full_key(observation, args.key)
        samples: queue.Queue[Observed] = queue.Queue()
        observation.subscribe(samples.put, key)
        last = time.monotonic()
        while True:
            try:
                o = samples.get(timeout=LOOK_PERIOD)
            except queue.Empty:
                if observation.ended.is_set():
                    print(f"umbra echo: {run_ended_text(observation)}", file=sys.stderr)
                    return 1
                if args.timeout is not None and time.monotonic() - last > args.timeout:
                    print(f"umbra echo: no sample on {key} for {args.timeout:g} s", file=sys.stderr)
                    return 1
                continue
            last = time.monotonic()
            if o.kind == "end":
                print(f"umbra echo: {key}: the producer ended the stream", file=sys.stderr)
                return 0
            if o.kind == "undecodable":
                print(f"umbra echo: {key}: undecodable sample: {o.error}", file=sys.stderr)
                continue
            _print(o, args.json)
            if args.once:
                return 0
    finally:
        observation.close()


def _print(o: Observed, as_json: bool) -> None:
    fields = message_fields(o.message) if o.message is not None else {}
    if as_json:
        print(json_text({"key": o.key, "type": o.type_name, **fields}), flush=True)
        return
    print(f"--- {o.key} ({o.type_name}, {o.size} bytes)")
    for name, value in fields.items():
        print(f"{name}: {json_text(value)}")
    sys.stdout.flush()
