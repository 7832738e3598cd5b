"""Options and helpers shared by ``umbra topics``, ``echo`` and ``hz``: joining a run as an
observer (``umbra.runtime.links.observe``) and naming a key."""

from __future__ import annotations

import argparse
import math
from typing import Any

import msgspec
import numpy as np

from umbra.connectors.errors import UserError
from umbra.connectors.messages import Message
from umbra.runtime.links.observe import Observation

#: Arrays with more elements than this are summarised (dtype, shape, range) when printed.
MAX_LISTED = 64


def add_observer_args(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--graph",
        metavar="NAME",
        help="the graph to observe (its name or key prefix) when "
        "this user runs several on this host",
    )
    parser.add_argument(
        "--run",
        metavar="RUN",
        help="one of several runs of the graph "
        "(launcher-PID or by-hand, as the error listing them says)",
    )
    parser.add_argument(
        "--zenoh-config",
        metavar="FILE",
        help="observe a run elsewhere: an observer configuration written by `umbra keys GRAPH "
        "--observer NAME` (with --connect and --graph or --prefix)",
    )
    parser.add_argument(
        "--connect",
        action="append",
        default=[],
        metavar="ENDPOINT",
        help="with --zenoh-config: an endpoint of a process of the run (repeatable: peers do "
        "not route for each other, so give every process whose outputs you want)",
    )
    parser.add_argument("--prefix", metavar="KEY", help="the run's key prefix (with --connect)")


def open_observation(args: argparse.Namespace) -> Observation:
    """Join the run the options name; UserError (exit 2) when none runs or access is refused."""
    return Observation.open(
        args.graph,
        prefix=args.prefix,
        zenoh_config=args.zenoh_config,
        connect=args.connect,
        run_id=args.run,
    )


def full_key(observation: Observation, key: str) -> str:
    """``key`` under the run's prefix when it is given relative (``module/port``); UserError
    when the observer may not read it (no such output, an output not published, a key its
    credentials leave out)."""
    if not key.startswith(observation.prefix + "/"):
        key = f"{observation.prefix}/{key.strip('/')}"
    readable = observation.keys
    if readable is None or key in readable:
        return key
    run = observation.run
    outputs = sorted(o.key for p in run.processes for o in p.outputs) if run else []
    if key in outputs:
        raise UserError(
            f"error: `{key}` feeds no other process, so it is not published; run the graph "
            f"with --publish-all to observe every output"
        )
    where = f"graph `{run.graph}`" if run else "this observer"
    raise UserError(
        f"error: expected a key {where} may read, found `{key}`; readable: "
        f"{', '.join(readable) or 'none'}"
    )


def _plain(value: Any) -> Any:
    """``value`` as JSON-ready data: big arrays summarised, non-finite floats as strings."""
    if isinstance(value, np.ndarray):
        if value.size <= MAX_LISTED:
            return _plain(value.tolist())
        out: dict[str, Any] = {"dtype": str(value.dtype), "shape": list(value.shape)}
        if value.size and value.dtype.kind in "biuf":
            out.update(min=_plain(value.min().item()), max=_plain(value.max().item()))
        return out
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    return value


def message_fields(msg: Message) -> dict[str, Any]:
    """Every field of ``msg``, JSON-ready (``_plain``)."""
    return {k: _plain(v) for k, v in msgspec.structs.asdict(msg).items()}
