"""Holding the host's CPU wake-up latency low while a process runs (Linux PM QoS).

An idle CPU sleeps in an idle state; waking it for an incoming sample costs that state's exit
latency, and on a virtual machine a halted virtual CPU is woken through the hypervisor (on the
development VM, holding the latency at 0 took a raw zenoh round trip from about 180 to 97 µs).
Real-time hosts bound it: a process writes the
largest latency it tolerates [µs] to ``/dev/cpu_dma_latency`` as a 32-bit integer and keeps the
file open; the kernel then uses no idle state slower than that, on every CPU, until the file is
closed (0: idle CPUs poll). ``cyclictest`` and most real-time Linux guides do this. It costs power:
ask for it in the process that closes the servo loop, not everywhere.

Writing the file needs root (or a udev rule giving the user write access). A process that cannot
hold the latency runs anyway, says why once in the log, and its summary records it.
"""

from __future__ import annotations

import logging
import os
import struct
from pathlib import Path
from types import TracebackType
from typing import Any

PM_QOS_FILE = Path("/dev/cpu_dma_latency")
#: The kernel's default request, "no constraint" [µs] (2000 s).
NO_CONSTRAINT_US = 2_000_000_000


def is_latency_us(value: object) -> bool:
    """Whether ``value`` is a limit the kernel takes: a whole number of µs, 0 to 2000 s."""
    return isinstance(value, int) and not isinstance(value, bool) and 0 <= value <= NO_CONSTRAINT_US


class CpuLatencyHold:
    """From ``acquire()`` to ``release()`` (or as a context manager), asks the kernel to keep
    every CPU's wake-up latency at most ``limit_us`` [µs]; ``None`` asks nothing, and neither
    does a hold given an ``unneeded`` reason (it only records it). Never raises for a host that
    refuses: ``held`` and ``reason`` say what happened, and ``summary()`` goes into the run
    summary."""

    def __init__(
        self,
        limit_us: int | None,
        log: logging.Logger | None = None,
        path: Path = PM_QOS_FILE,
        unneeded: str = "",
    ) -> None:
        self.limit_us = limit_us
        self.path = path
        self.held = False
        self.reason = unneeded
        self._log = log or logging.getLogger("umbra")
        self._fd: int | None = None

    def __enter__(self) -> CpuLatencyHold:
        self.acquire()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.release()

    def acquire(self) -> None:
        """Open the file and write the limit (nothing when none is asked or it is unneeded)."""
        if self.limit_us is None or self.reason:
            return
        try:
            fd = os.open(self.path, os.O_WRONLY)
        except OSError as exc:
            self.reason = f"cannot open {self.path}: {exc.strerror or exc}"
        else:
            try:
                os.write(fd, struct.pack("=i", self.limit_us))
            except OSError as exc:
                os.close(fd)
                self.reason = f"cannot write {self.path}: {exc.strerror or exc}"
            else:
                self._fd, self.held = fd, True
        if self.held:
            self._log.info("holding every CPU's wake-up latency at most %d µs", self.limit_us)
        else:
            self._log.warning(
                "cpu_latency_us %d not held (%s; it needs root or write access to %s): "
                "running with the host's idle states",
                self.limit_us,
                self.reason,
                self.path,
            )

    def release(self) -> None:
        """Close the file, which ends the request (safe to call when nothing is held)."""
        if self._fd is not None:
            os.close(self._fd)  # the kernel drops the request with the file
            self._fd = None

    def summary(self) -> dict[str, Any]:
        """What the run summary says: the limit asked [µs], whether it was held, why not."""
        out: dict[str, Any] = {"cpu_latency_us": self.limit_us, "held": self.held}
        if self.reason:
            out["reason"] = self.reason
        return out


def current_cpu_latency_us(path: Path = PM_QOS_FILE) -> int:
    """The latency the kernel enforces now [µs]: the smallest request of any process
    (``NO_CONSTRAINT_US`` when none); OSError when the file cannot be read (not root)."""
    with open(path, "rb") as f:
        return int(struct.unpack("=i", f.read(4))[0])


def latency_limit(
    requests: dict[str, int], process: str | None, override: int | None = None
) -> int | None:
    """The limit [µs] a process holds: ``override`` (the command line) when given, else what the
    graph asks for ``process``; with every module in one process (``process`` None), the
    strictest request of any process. None: hold nothing."""
    if override is not None:
        return override
    if process is not None:
        return requests.get(process)
    return min(requests.values(), default=None)
