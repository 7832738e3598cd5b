"""Options and helpers shared by ``umbra topics``, ``echo`` and ``hz``: joining a run as an
observer (``umbra.runtime.links.observe``) and naming a key."""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING, Any

import msgspec

from umbra.connectors.errors import UserError

if TYPE_CHECKING:  # imported where used: `umbra --help` loads this file without them
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
        metavar="ID",
        help="the run to observe when several runs of the graph are up (its run ID, which "
        "`umbra run` says on start and `umbra topics` lists; default: the newest)",
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


def open_observation(args: argparse.Namespace, list_runs: bool = False) -> Observation:
    """Join the run the options name and say on stderr, in one line, which run (and, when it
    was taken as the newest of several, the others and how to choose); ``list_runs``: one
    more line per run of the graph when several are up. UserError (exit 2) when none runs or
    access is refused."""
    from umbra.runtime.links.observe import Observation, runs_text, sibling_runs

    observation = Observation.open(
        args.graph,
        prefix=args.prefix,
        zenoh_config=args.zenoh_config,
        connect=args.connect,
        run_id=args.run,
    )
    run = observation.run
    if run is None:
        return observation
    others = sibling_runs(run)
    line = f"umbra {args.command}: attached to run {run.describe()}"
    if others and args.run is None:
        also = "listed below" if list_runs else f"also {runs_text(others)}"
        line += (
            f"; the newest of {len(others) + 1} runs of this graph ({also}): choose one with "
            f"--run ID"
        )
    print(line, file=sys.stderr, flush=True)
    if list_runs and others:
        print(f"runs of graph `{run.graph}` on this host, newest first:", file=sys.stderr)
        for each in sorted([run, *others], key=lambda r: r.started, reverse=True):
            mark = "*" if each is run else " "
            print(f" {mark} {each.describe()}", file=sys.stderr)
        sys.stderr.flush()
    return observation


def run_ended_text(observation: Observation) -> str:
    """What a tool says when the run it is attached to has ended."""
    run = observation.run
    name = run.run_id if run is not None else observation.prefix
    return f"run {name} ended (none of its processes is running)"


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
    """``value`` as JSON-ready data: big arrays summarised (a float that is not finite is
    written ``null`` by :func:`umbra.connectors.json_text.json_text`)."""
    import numpy as np  # loaded by the messages it is given; `umbra --help` loads this file

    if isinstance(value, np.ndarray):
        if value.size <= MAX_LISTED:
            return _plain(value.tolist())
        out: dict[str, Any] = {"dtype": str(value.dtype), "shape": list(value.shape)}
        if value.size and value.dtype.kind in "biuf":
            out.update(min=_plain(value.min().item()), max=_plain(value.max().item()))
        return out
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    return value


def message_fields(msg: Message) -> dict[str, Any]:
    """Every field of ``msg``, JSON-ready (``_plain``)."""
    return {k: _plain(v) for k, v in msgspec.structs.asdict(msg).items()}
