"""Run files: how an observer of this user finds the graphs running on this host, with no setup.

Each process of a split graph writes, while it runs, one file into the user's private folder
(``umbra.runtime.links.host_auth.secret_folder``, mode 0700; the file mode 0600): the graph's name
and key prefix, the process's name and pid, the endpoints it listens on, the observer credentials of
the run (``umbra.runtime.links.acl.Observer``: read every output key and the liveliness tokens,
nothing else) and the outputs of its modules with their keys and types. ``umbra topics`` and the
observer API (``umbra.runtime.links.observe``) read them; a file whose process is gone is ignored
and removed. Only this user can read them: the observer password is as private as the secret.
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from umbra.runtime.graph.plan import GraphPlan
from umbra.runtime.links.acl import output_key
from umbra.runtime.links.host_auth import private_folder, secret_folder, secret_name
from umbra.runtime.links.pool import pid_alive

RUNS = "runs"
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
    #: the run the process belongs to: ``launcher-PID`` under a launcher, ``by-hand`` otherwise
    run_id: str = "by-hand"


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
