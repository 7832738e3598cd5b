"""The children of a split run as the launcher sees them, and the summaries of the run: each
process's ``summary-NAME.json`` (written for it when it died without one) and ``summary.json``."""

from __future__ import annotations

import contextlib
import json
import signal
import subprocess
import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import msgspec

from umbra.connectors.json_text import json_text
from umbra.runtime.graph.plan import GraphPlan
from umbra.runtime.links.config import Endpoints
from umbra.runtime.links.control_line import ControlCommand


@dataclass
class Child:
    name: str
    endpoints: Endpoints
    popen: subprocess.Popen[bytes]
    servo: bool
    tail: deque[str] = field(default_factory=lambda: deque(maxlen=8))
    told_at: float | None = None
    told: ControlCommand | None = None  #: the launcher's last command to it (None: none yet)
    termed: bool = False
    code: int | None = None
    segments: set[str] = field(default_factory=set)  #: /dev/shm files it was seen to map

    @property
    def running(self) -> bool:
        return self.code is None


def read_summary(out: Path, child: Child) -> dict[str, Any] | None:
    path = out / f"summary-{child.name}.json"
    try:
        summary: dict[str, Any] = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return summary


class _Reason(msgspec.Struct):
    """The one field of a process's summary that the launcher needs as the process ends."""

    reason: str = ""


def reason_of(out: Path, child: Child) -> str:
    """Why ``child`` ended: its summary's ``reason`` (decoded alone: a summary holds a run's
    records, and a starved launcher tells the other processes only once it has read this; a
    summary that is not strict JSON, such as one holding ``NaN`` as Python's ``json`` writes it,
    is read whole), else its last line on stderr."""
    try:
        text = (out / f"summary-{child.name}.json").read_bytes()
    except OSError:
        text = b""
    reason: object = ""
    try:
        reason = msgspec.json.decode(text, type=_Reason).reason
    except msgspec.ValidationError:
        pass  # JSON, but its reason is not words
    except msgspec.DecodeError:
        with contextlib.suppress(ValueError, AttributeError):
            reason = json.loads(text).get("reason", "")
    if isinstance(reason, str) and reason:
        return reason
    return child.tail[-1] if child.tail else "no reason given"


def cause_of(out: Path, child: Child) -> str:
    rc = child.code
    assert rc is not None
    if rc < 0:
        try:
            name = signal.Signals(-rc).name
        except ValueError:
            name = f"signal {-rc}"
        return f"died: killed by {name}"
    return f"failed (exit {rc}): {reason_of(out, child)}"


def write_summaries(
    plan: GraphPlan,
    out: Path,
    children: list[Child],
    code: int,
    reason: str,
    started: float,
    run_id: str = "",
) -> None:
    processes = []
    for child in children:
        summary = read_summary(out, child)
        if summary is None:  # died before writing one
            summary = {
                "process": child.name,
                "exit_code": child.code,
                "reason": cause_of(out, child) if child.code else "no summary written",
                "modules": [],
            }
            path = out / f"summary-{child.name}.json"
            path.write_text(json_text(summary, indent=2))
        processes.append(
            {
                "process": child.name,
                "pid": child.popen.pid,
                "exit_code": child.code,
                "reason": summary.get("reason", ""),
                "servo_side": child.servo,
                "listen": child.endpoints.listen,
                "connect": child.endpoints.connect,
            }
        )
    whole = {
        "graph": plan.spec.name,
        "run_id": run_id,
        "mode": "split",
        "exit_code": code,
        "reason": reason,
        "wall_time_s": round(time.time() - started, 3),
        "key_prefix": plan.key_prefix,
        "processes": processes,
    }
    (out / "summary.json").write_text(json_text(whole, indent=2))
