"""The simulated ROS 2 robot (``examples/ros2_robot``, on zenoh-ros2-sdk) in a process of its
own, and the verdict it writes when the gripper has closed."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]


def start_robot(router: str, verdict: Path, *args: str) -> subprocess.Popen[str]:
    """``python -m examples.ros2_robot --router ROUTER --verdict VERDICT ARGS`` (output piped)."""
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), env.get("PYTHONPATH", "")) if p)
    return subprocess.Popen(
        [
            sys.executable,
            "-m",
            "examples.ros2_robot",
            *("--router", router, "--verdict", str(verdict)),
            *args,
        ],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env=env,
    )


def judged(verdict: Path) -> dict[str, Any] | None:
    """The robot's record once it has judged a grasp (None before)."""
    if not verdict.is_file():
        return None
    record = json.loads(verdict.read_text())
    return record if record.get("judged") else None


def interrupt(proc: subprocess.Popen[str], timeout_s: float = 60.0) -> tuple[int, str, str]:
    """SIGINT ``proc`` (a Ctrl-C), then its exit code, stdout and stderr (killed after
    ``timeout_s`` [s])."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
    try:
        out, err = proc.communicate(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        proc.kill()
        out, err = proc.communicate()
    return proc.returncode, out or "", err or ""
