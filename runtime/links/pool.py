"""Zero-copy frames between processes on one host: a shared-memory pool per large output.

zenoh-python gives no writable or readable view of its shared-memory buffers, so a frame sent
through zenoh's shared memory is copied three times per hop (encode, into the buffer, out of it).
For large samples on best-effort links (video) whose consumers all run on this host, the
producer instead writes the sample once into a slot of its own pool (a file in ``/dev/shm``) and
publishes a small descriptor on the link's key; the consumer decodes the sample straight from the
slot: its arrays are read-only views on the shared memory, no copy at all.

Lifetime: each slot has one busy flag per consumer process of the key. The producer sets them when
it fills the slot and never reuses a slot while a flag is set; a consumer clears its flag when the
last array of the sample is garbage collected (``weakref.finalize``), or at once when it drops the
sample. Flags of a consumer process that has died (its pid no longer exists) are cleared by the
producer. When no slot is free, or the sample does not fit, the sample takes the ordinary zenoh
path (counted), so a consumer that hoards frames slows nothing down and corrupts nothing.

Pool file: a 4096-byte header (magic, slot count, slot size, consumer count, then the flags,
``slots x consumers`` bytes), then the slots; each slot starts with its generation and length
(u64 each) in a 64-byte head. Descriptor: ``b"UMBp"``, pool name, slot, generation, length.
"""

from __future__ import annotations

import contextlib
import mmap
import os
import re
import secrets
import struct
import weakref
from collections.abc import Callable
from pathlib import Path

import numpy as np

SHM_DIR = Path("/dev/shm")
POOL_MAGIC = b"UMBPOOL1"
DESCRIPTOR_MAGIC = b"UMBp"
NAME_RE = re.compile(r"^umbra-pool-\d+-\d+-[0-9a-f]{16}$")
_STALE_RE = re.compile(r"^umbra-(?:pool|host)-(\d+)-(\d+)-[0-9a-f]{16}$")
MARKER_RE = re.compile(r"^(\d+)-(\d+)-[0-9a-f]{16}$")


def _pid_namespace() -> int:
    """Inode of this process's pid namespace: pids in file names are only checked within it."""
    try:
        return os.stat("/proc/self/ns/pid").st_ino
    except OSError:
        return 0


PID_NS = _pid_namespace()
_HEADER = 4096
_HEAD = struct.Struct("<8sIII")  # magic, slots, slot size, consumers
_SLOT_HEAD = 64
_SLOT = struct.Struct("<QQ")  # generation, length
_DESC = struct.Struct("<4s48sIQQ")  # magic, pool name, slot, generation, length
MAX_CONSUMERS = 64
DEFAULT_SLOTS = 16


def shm_available() -> bool:
    """Whether this host has a writable /dev/shm."""
    return SHM_DIR.is_dir() and os.access(SHM_DIR, os.W_OK)


class FramePool:
    """Producer side: ``slots`` slots of ``slot_size`` bytes shared with ``consumers`` processes."""

    def __init__(self, frame_size: int, consumers: int, slots: int = DEFAULT_SLOTS) -> None:
        if not 0 < consumers <= MAX_CONSUMERS or slots * consumers > _HEADER - _HEAD.size:
            raise ValueError(f"a pool serves 1..{MAX_CONSUMERS} consumers, asked for {consumers}")
        self.name = f"umbra-pool-{PID_NS}-{os.getpid()}-{secrets.token_hex(8)}"
        self.slots, self.consumers = slots, consumers
        self.slot_size = (_SLOT_HEAD + frame_size + frame_size // 8 + 4095) // 4096 * 4096
        self.path = SHM_DIR / self.name
        fd = os.open(self.path, os.O_CREAT | os.O_EXCL | os.O_RDWR, 0o600)
        try:
            os.ftruncate(fd, _HEADER + slots * self.slot_size)
            self._mm = mmap.mmap(fd, _HEADER + slots * self.slot_size)
        finally:
            os.close(fd)
        self._mm[: _HEAD.size] = _HEAD.pack(POOL_MAGIC, slots, self.slot_size, consumers)
        self._flags = np.frombuffer(self._mm, np.uint8, slots * consumers, _HEAD.size).reshape(
            slots, consumers
        )
        self._generation = 0

    def write(self, head: bytes, parts: list[tuple[int, np.ndarray]], size: int) -> bytes | None:
        """Put a framed sample (``Codec.frame``) in a free slot; the descriptor to publish, or
        None when no slot is free or the sample does not fit."""
        if _SLOT_HEAD + size > self.slot_size:
            return None
        slot = self._free_slot()
        if slot is None:
            return None
        self._generation += 1
        start = _HEADER + slot * self.slot_size
        data = start + _SLOT_HEAD
        mm = self._mm
        mm[data : data + len(head)] = head
        body = data + len(head)
        for offset, arr in parts:
            flat = arr.reshape(-1).view(np.uint8)
            np.copyto(np.frombuffer(mm, np.uint8, flat.size, body + offset), flat)
        mm[start : start + _SLOT.size] = _SLOT.pack(self._generation, size)
        self._flags[slot, :] = 1
        return _DESC.pack(DESCRIPTOR_MAGIC, self.name.encode(), slot, self._generation, size)

    def _free_slot(self) -> int | None:
        """The lowest free slot: recently used memory is still in the CPU caches."""
        free = np.flatnonzero(~self._flags.any(axis=1))
        return int(free[0]) if free.size else None

    def release_consumer(self, index: int) -> None:
        """Clear every flag of consumer ``index`` (its process is gone)."""
        self._flags[:, index] = 0

    @property
    def busy(self) -> int:
        """Slots in use."""
        return int(self._flags.any(axis=1).sum())

    def close(self) -> None:
        """Remove the pool file (consumers that still map it keep their views)."""
        with contextlib.suppress(FileNotFoundError):
            self.path.unlink()
        self._flags = np.zeros((self.slots, self.consumers), np.uint8)
        with contextlib.suppress(BufferError):  # views still exported: left to the GC
            self._mm.close()


class PoolReader:
    """Consumer side: maps producers' pools and hands out read-only views on their slots."""

    def __init__(self) -> None:
        self._maps: dict[str, tuple[mmap.mmap, int, int, int]] = {}

    def _map(self, name: str) -> tuple[mmap.mmap, int, int, int]:
        found = self._maps.get(name)
        if found is None:
            if not NAME_RE.match(name):
                raise ValueError(f"not an umbra pool name: {name!r}")
            fd = os.open(SHM_DIR / name, os.O_RDWR)
            try:
                mm = mmap.mmap(fd, 0)
            finally:
                os.close(fd)
            magic, slots, slot_size, consumers = _HEAD.unpack_from(mm)
            if magic != POOL_MAGIC or len(mm) < _HEADER + slots * slot_size:
                raise ValueError(f"pool {name} has a bad header")
            found = self._maps[name] = (mm, slots, slot_size, consumers)
        return found

    def open(self, descriptor: bytes, index: int) -> tuple[memoryview, Callable[[], None]]:
        """A read-only view on the sample ``descriptor`` names, and the function that releases
        it now; the slot is also released when the view's last user is garbage collected.
        ValueError (or OSError) when the descriptor is not a valid one for consumer ``index``."""
        _magic, raw_name, slot, generation, length = _DESC.unpack(descriptor)
        name = raw_name.rstrip(b"\0").decode("ascii")
        mm, slots, slot_size, consumers = self._map(name)
        if not (0 <= slot < slots and 0 <= index < consumers and length + _SLOT_HEAD <= slot_size):
            raise ValueError("pool descriptor out of bounds")
        flag = _HEAD.size + slot * consumers + index
        released = [False]

        def release() -> None:
            if not released[0]:
                released[0] = True
                mm[flag] = 0

        start = _HEADER + slot * slot_size
        stored_generation, stored_length = _SLOT.unpack_from(mm, start)
        if (stored_generation, stored_length) != (generation, length):
            raise ValueError("pool slot holds another sample (stale descriptor)")
        base = np.frombuffer(mm, np.uint8, length, start + _SLOT_HEAD)
        weakref.finalize(base, release)
        return memoryview(base).toreadonly(), release


def is_descriptor(data: bytes) -> bool:
    """Whether ``data`` is a pool descriptor rather than a sample."""
    return len(data) == _DESC.size and data[:4] == DESCRIPTOR_MAGIC


def pid_alive(pid: int) -> bool:
    """Whether process ``pid`` exists on this host and is not a zombie."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return True
    return "\nState:\tZ" not in status


def sweep_stale() -> int:
    """Remove pool and marker files left by processes that died without cleaning up."""
    removed = 0
    with contextlib.suppress(OSError):
        for entry in os.scandir(SHM_DIR):
            match = _STALE_RE.match(entry.name)
            if match and int(match.group(1)) == PID_NS and not pid_alive(int(match.group(2))):
                with contextlib.suppress(OSError):
                    os.unlink(entry.path)
                    removed += 1
    return removed


class HostMarker:
    """A file in /dev/shm named after this process: another process that sees it shares this
    process's shared memory (same host, same /dev/shm) and learns its pid from the name."""

    def __init__(self) -> None:
        self.id = "none"
        self.path: Path | None = None
        if not shm_available():
            return
        sweep_stale()
        marker = f"{PID_NS}-{os.getpid()}-{secrets.token_hex(8)}"
        path = SHM_DIR / f"umbra-host-{marker}"
        with contextlib.suppress(OSError):
            path.touch(mode=0o600)
            self.id, self.path = marker, path

    def close(self) -> None:
        if self.path is not None:
            with contextlib.suppress(OSError):
                self.path.unlink()
            self.path = None


def marker_pid(marker: str) -> int | None:
    """The pid behind another process's marker when it is visible here (same /dev/shm) and in
    this pid namespace (so its death can be checked), else None."""
    match = MARKER_RE.match(marker)
    if match is None or int(match.group(1)) != PID_NS:
        return None
    if not (SHM_DIR / f"umbra-host-{marker}").exists():
        return None
    return int(match.group(2))
