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

Forwarding: a consumer that publishes a sample whose arrays still lie in a slot it holds (a relay,
a module that passes a frame on) does not copy them. It sets the flags of its own consumers on
that slot — while its own flag is still set, so the slot cannot be reused meanwhile — and
publishes a forward descriptor carrying the new sample's header, whose array references point
into the slot. Flags are indexed by (setter, holder) process pairs: only the setter of a flag
ever sets it, and only when it is clear; only the holder clears it, so no flag is ever written by
two processes at once and no hold is lost.

Pool file: a 4096-byte header (magic, slot count, slot size, consumer count, then the flags,
``slots x consumers`` bytes), then the slots; each slot starts with its generation and length
(u64 each) in a 64-byte head. Descriptor: ``b"UMBp"``, pool name, slot, generation, length.
Forward descriptor: ``b"UMBf"``, pool name, slot, generation, length, header length, then the
header (``Codec.frame_header``), array offsets counted from the start of the slot's data.
"""

from __future__ import annotations

import contextlib
import mmap
import os
import re
import secrets
import stat
import struct
import weakref
from collections.abc import Callable
from pathlib import Path

import numpy as np

SHM_DIR = Path("/dev/shm")
POOL_MAGIC = b"UMBPOOL1"
DESCRIPTOR_MAGIC = b"UMBp"
FORWARD_MAGIC = b"UMBf"
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
_FWD = struct.Struct("<4s48sIQQI")  # the same, then the length of the header that follows
MAX_CONSUMERS = 255
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
        self._idle_row = bytes(consumers)
        self._name = self.name.encode()
        self._views: dict[int, np.ndarray] = {}  # slot -> uint8 view of its data (no re-creation)

    def write(
        self,
        head: bytes,
        parts: list[tuple[int, np.ndarray]],
        size: int,
        columns: list[int] | None = None,
    ) -> bytes | None:
        """Put a framed sample (``Codec.frame``) in a free slot and set the flags ``columns``
        (all when None); the descriptor to publish, or None when no slot is free or the sample
        does not fit."""
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
        view = self._views.get(slot)
        if view is None:
            view = self._views[slot] = np.frombuffer(mm, np.uint8, self.slot_size, start)
        for offset, arr in parts:
            flat = arr.reshape(-1).view(np.uint8)
            at = _SLOT_HEAD + len(head) + offset
            np.copyto(view[at : at + flat.size], flat)
        mm[start : start + _SLOT.size] = _SLOT.pack(self._generation, size)
        row = _HEAD.size + slot * self.consumers
        for column in range(self.consumers) if columns is None else columns:
            mm[row + column] = 1
        return _DESC.pack(DESCRIPTOR_MAGIC, self._name, slot, self._generation, size)

    def _free_slot(self) -> int | None:
        """The lowest free slot: recently used memory is still in the CPU caches."""
        mm, n, idle = self._mm, self.consumers, self._idle_row
        row = _HEAD.size
        for slot in range(self.slots):
            if mm[row : row + n] == idle:
                return slot
            row += n
        return None

    def release_consumer(self, index: int | list[int]) -> None:
        """Clear every flag of column(s) ``index`` (its process is gone)."""
        self._flags[:, index] = 0

    @property
    def busy(self) -> int:
        """Slots in use."""
        return int(self._flags.any(axis=1).sum())

    def close(self) -> None:
        """Remove the pool file (consumers that still map it keep their views)."""
        with contextlib.suppress(FileNotFoundError):
            self.path.unlink()
        self._views.clear()
        self._flags = np.zeros((self.slots, self.consumers), np.uint8)
        with contextlib.suppress(BufferError):  # views still exported: left to the GC
            self._mm.close()


class PoolReader:
    """Consumer side: maps producers' pools, hands out read-only views on their slots, and finds
    the slot an outgoing array lies in (forwarding)."""

    def __init__(self) -> None:
        self._maps: dict[str, tuple[mmap.mmap, int, int, int]] = {}
        self._ranges: list[tuple[int, int, str]] = []  # [address, end) of each mapped pool

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
            address = np.frombuffer(mm, np.uint8, 1).ctypes.data
            self._ranges.append((address, address + len(mm), name))
        return found

    def open(self, descriptor: bytes, index: int) -> tuple[memoryview, Callable[[], None]]:
        """A read-only view on the sample ``descriptor`` names, and the function that releases
        it now; the slot is also released when the view's last user is garbage collected.
        ValueError (or OSError) when the descriptor is not a valid one for consumer ``index``."""
        _magic, raw_name, slot, generation, length = _DESC.unpack(descriptor)
        return self._view(raw_name, slot, generation, length, index)

    def open_forward(
        self, descriptor: bytes, index: int
    ) -> tuple[memoryview, Callable[[], None], bytes]:
        """``open`` for a forward descriptor: the slot's view, its release, and the header of
        the forwarded sample (decode with ``Codec.decode_placed``)."""
        if len(descriptor) < _FWD.size:
            raise ValueError("truncated forward descriptor")
        _magic, raw_name, slot, generation, length, header_len = _FWD.unpack_from(descriptor)
        header = descriptor[_FWD.size :]
        if len(header) != header_len:
            raise ValueError("forward descriptor header has the wrong length")
        view, release = self._view(raw_name, slot, generation, length, index)
        return view, release, header

    def _view(
        self, raw_name: bytes, slot: int, generation: int, length: int, index: int
    ) -> tuple[memoryview, Callable[[], None]]:
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
        return base.data.toreadonly(), release

    def slot_of(self, arr: np.ndarray) -> tuple[str, int, int] | None:
        """(pool, slot, offset from the slot's data) of the memory of ``arr`` when it lies
        wholly in the sample held by one slot of a mapped pool, else None."""
        if not self._ranges:
            return None
        address = arr.__array_interface__["data"][0]
        for low, high, name in self._ranges:
            if low <= address < high:
                mm, slots, slot_size, _consumers = self._maps[name]
                slot, within = divmod(address - low - _HEADER, slot_size)
                offset = within - _SLOT_HEAD
                if not 0 <= slot < slots or offset < 0:
                    return None
                _generation, length = _SLOT.unpack_from(mm, _HEADER + slot * slot_size)
                if offset + arr.nbytes > length:
                    return None
                return name, slot, offset
        return None

    def forward(self, name: str, slot: int, columns: list[int], header: bytes) -> bytes | None:
        """Hold slot ``slot`` of pool ``name`` for ``columns`` and return the forward descriptor
        of ``header`` — or None (nothing held) when one of those flags is still set (that
        consumer still holds an earlier forward of this slot). Call only while holding the slot
        yourself (the arrays being sent keep it held)."""
        mm, _slots, slot_size, consumers = self._maps[name]
        row = _HEAD.size + slot * consumers
        for column in columns:
            if mm[row + column]:
                return None
        generation, length = _SLOT.unpack_from(mm, _HEADER + slot * slot_size)
        for column in columns:
            mm[row + column] = 1
        return (
            _FWD.pack(FORWARD_MAGIC, name.encode(), slot, generation, length, len(header)) + header
        )


def is_descriptor(data: bytes) -> bool:
    """Whether ``data`` is a pool descriptor rather than a sample."""
    return len(data) == _DESC.size and data[:4] == DESCRIPTOR_MAGIC


def is_forward(data: bytes) -> bool:
    """Whether ``data`` is a forward descriptor (a relayed sample still in a producer's pool)."""
    return data[:4] == FORWARD_MAGIC and len(data) >= _FWD.size


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
    """The pid behind another process's marker when it is visible here (same /dev/shm), owned
    by this user (a pool of ours is mode 0600: a process of another user could not read it) and
    in this pid namespace (so its death can be checked), else None."""
    match = MARKER_RE.match(marker)
    if match is None or int(match.group(1)) != PID_NS:
        return None
    try:
        st = os.lstat(SHM_DIR / f"umbra-host-{marker}")
    except OSError:
        return None
    if st.st_uid != os.geteuid() or not stat.S_ISREG(st.st_mode):
        return None
    return int(match.group(2))
