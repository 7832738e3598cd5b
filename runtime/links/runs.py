"""Run files: how an observer of this user finds the graphs running on this host, with no setup.

Each process of a split graph writes, while it runs, one file into the user's private folder
(``umbra.runtime.links.host_auth.secret_folder``, mode 0700; the file mode 0600): the graph's name
and key prefix, the run it belongs to (its run ID, the launcher's pid, how many processes the run
has), the process's name and pid, the endpoints it listens on, the observer credentials of the run
(``umbra.runtime.links.acl.Observer``: read every output key and the liveliness tokens, nothing
else) and the outputs of its modules with their keys and types. ``umbra topics`` and the observer
API (``umbra.runtime.links.observe``) read them; a file whose process is gone is ignored and
removed. Only this user can read them: the observer password is as private as the secret.

The run ID is made once by the launcher (:func:`new_run_id`) and given to every process it starts
(``--run-id``), so that the files of one run are told from those of another run of the same graph
before, while and after they are written. Processes started by hand belong to the run ``by-hand``
unless ``--run-id`` names another.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import secrets
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from umbra.connectors.errors import UserError
from umbra.runtime.graph.plan import GraphPlan
from umbra.runtime.links.acl import output_key
from umbra.runtime.links.host_auth import private_folder, secret_folder, secret_name
from umbra.runtime.links.pool import pid_alive

RUNS = "runs"
#: The run ID of processes started by hand without ``--run-id``.
BY_HAND = "by-hand"
#: What a run ID may hold (it names a run in messages and options, never a key or a path).
RUN_ID_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.\-]{0,127}$")
#: How a run lets observers in: its credentials (``observer`` holds them), anyone
#: (``--insecure``), or a zenoh configuration file of its own (TLS: ``umbra keys --observer``).
ACCESS = ("credentials", "insecure", "config")


@dataclass
class OutputEntry:
    """One output of a module of the process."""

    key: str
    type: str
    module: str
    port: str
    #: True when it crosses processes (always published); else only with ``--publish-all``
    link: bool
    #: processes of the graph consuming it over a link
    consumers: list[str] = field(default_factory=list)


@dataclass
class RunFile:
    """What one running process tells observers of its user."""

    graph: str
    prefix: str
    process: str
    pid: int
    listen: list[str]
    access: str
    publish_all: bool
    outputs: list[OutputEntry]
    observer: dict[str, str] | None = None  #: ``{"user", "password"}`` when access is credentials
    started: float = 0.0  #: wall-clock time of the start [s since the epoch]
    #: the run the process belongs to: made by the launcher (:func:`new_run_id`), else ``BY_HAND``
    run_id: str = BY_HAND
    launcher: int = 0  #: pid of the launcher that started the process (0: started by hand)
    #: when the launcher started the run [s since the epoch]; 0: started by hand (``started``)
    run_started: float = 0.0
    run_processes: int = 0  #: how many processes the run has (0: not said)


def new_run_id(graph: str) -> str:
    """A new run's ID: ``<graph>-<YYYYmmdd-HHMMSS>-<4 hex>`` (local time; the random part tells
    apart two runs started in the same second)."""
    return f"{graph}-{time.strftime('%Y%m%d-%H%M%S')}-{secrets.token_hex(2)}"


def checked_run_id(value: str, option: str = "--run-id") -> str:
    """``value`` when it is a run ID (``RUN_ID_RE``); UserError saying what was expected."""
    if not RUN_ID_RE.match(value):
        raise UserError(
            f"{option}: expected a run ID (letters, digits, `_`, `.`, `-`; at most 128, first a "
            f"letter or digit), found {value!r}"
        )
    return value


def runs_folder(folder: Path | None = None) -> Path:
    """The folder of run files (made private when missing)."""
    return (folder or secret_folder()) / RUNS


def describe_outputs(plan: GraphPlan, process: str) -> list[OutputEntry]:
    """Every output of the modules of ``process`` with its key, type and link consumers."""
    consumers: dict[str, set[str]] = {}
    for link in plan.links:
        consumers.setdefault(link.key, set()).add(plan.modules[link.connection.dst.module].process)
    found = []
    for name in plan.modules_in(process):
        for port, info in plan.modules[name].outputs.items():
            key = output_key(plan.key_prefix, name, port)
            found.append(
                OutputEntry(
                    key,
                    info.msg_type.__name__,
                    name,
                    port,
                    key in consumers,
                    sorted(consumers.get(key, ())),
                )
            )
    return found


def observer_endpoint(endpoint: str) -> str:
    """The endpoint an observer on this host connects to for a process listening on
    ``endpoint``: a wildcard address becomes loopback."""
    proto, _, rest = endpoint.partition("/")
    host, _, port = rest.rpartition(":")
    if host in ("0.0.0.0", "[::]"):
        host = "127.0.0.1" if host == "0.0.0.0" else "[::1]"
    return f"{proto}/{host}:{port}"


def write_run_file(entry: RunFile, folder: Path | None = None) -> Path:
    """Write ``entry`` (mode 0600) under its graph's and process's name; its path."""
    where = private_folder(folder or secret_folder())
    runs = where / RUNS
    with contextlib.suppress(FileExistsError):
        runs.mkdir(mode=0o700)
    name = f"{secret_name(entry.graph, entry.prefix)}.{entry.process}.{entry.pid}.json"
    path = runs / name
    fd, tmp = tempfile.mkstemp(dir=runs, prefix=".new-")  # mode 0600
    try:
        with os.fdopen(fd, "w") as f:
            json.dump(asdict(entry), f)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    return path


def _entry(data: dict[str, Any]) -> RunFile:
    outputs = [OutputEntry(**o) for o in data.pop("outputs")]
    return RunFile(outputs=outputs, **data)


def live_runs(folder: Path | None = None) -> list[RunFile]:
    """The run files of processes alive now (files of dead ones are removed), oldest first."""
    runs = runs_folder(folder)
    found = []
    try:
        names = sorted(p for p in runs.iterdir() if p.suffix == ".json")
    except OSError:
        return []
    for path in names:
        try:
            entry = _entry(json.loads(path.read_text()))
        except (OSError, ValueError, TypeError, KeyError):
            continue  # being written, or not ours
        if not pid_alive(entry.pid):
            with contextlib.suppress(OSError):
                path.unlink()
            continue
        found.append(entry)
    return sorted(found, key=lambda e: e.started)
