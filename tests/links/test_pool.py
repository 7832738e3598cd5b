"""The frame pool: slots held while any array of a sample lives, bad descriptors refused."""

from __future__ import annotations

import gc
import os
import struct

import numpy as np
import pytest

from umbra.connectors.codec import Codec
from umbra.connectors.messages import Image
from umbra.runtime.links.pool import (
    PID_NS,
    SHM_DIR,
    FramePool,
    HostMarker,
    PoolReader,
    is_descriptor,
    is_forward,
    marker_pid,
    sweep_stale,
)

pytestmark = pytest.mark.skipif(not SHM_DIR.is_dir(), reason="no /dev/shm on this host")


def _frame(seed: int) -> Image:
    pixels = np.random.default_rng(seed).integers(0, 256, (120, 160, 3), dtype=np.uint8)
    return Image(pixels=pixels, seq=seed)


def test_a_slot_is_reused_only_once_every_consumer_let_go() -> None:
    codec, reader = Codec(), PoolReader()
    first = _frame(1)
    head, parts, size = codec.frame(first)
    pool = FramePool(size, consumers=2, slots=2)
    try:
        d1 = pool.write(head, parts, size)
        assert d1 is not None and is_descriptor(d1)
        view_a, _ = reader.open(d1, 0)
        view_b, _ = reader.open(d1, 1)
        a, b = codec.decode(view_a), codec.decode(view_b)
        del view_a, view_b
        np.testing.assert_array_equal(a.pixels, first.pixels)
        assert not a.pixels.flags.writeable
        d2 = pool.write(*codec.frame(_frame(2)))
        assert d2 is not None and pool.busy == 2  # (sample 2 was never opened: still held)
        assert pool.write(*codec.frame(_frame(3))) is None  # both slots held: refused
        del b  # consumer 1 lets go of sample 1; consumer 0 still holds it
        gc.collect()
        assert pool.write(*codec.frame(_frame(3))) is None
        np.testing.assert_array_equal(a.pixels, first.pixels)  # intact
        del a
        gc.collect()
        assert pool.busy == 1
        d3 = pool.write(*codec.frame(_frame(3)))
        assert d3 is not None
        view, _release = reader.open(d3, 0)
        np.testing.assert_array_equal(codec.decode(view).pixels, _frame(3).pixels)
        with pytest.raises(ValueError, match="stale"):
            reader.open(d1, 0)  # slot 0 now holds sample 3
    finally:
        pool.close()
    assert not pool.path.exists()


def test_a_relayed_frame_is_forwarded_in_place_and_held_until_its_last_consumer_lets_go() -> None:
    """Process 0 produces into its pool for consumer 1 (column 1); 1 passes the frame on to 2
    (column 1 * 3 + 2 = 5) without copying; the slot stays busy until both let go."""
    codec, relay, last = Codec(), PoolReader(), PoolReader()
    first = _frame(1)
    head, parts, size = codec.frame(first)
    pool = FramePool(size, consumers=9, slots=1)
    try:
        d1 = pool.write(head, parts, size, [1])
        assert d1 is not None
        view, _ = relay.open(d1, 1)
        got = codec.decode(view)
        del view
        passed_on = Image(pixels=got.pixels, seq=7, stamp=2.5, frame="wrist")
        where = relay.slot_of(passed_on.pixels)
        assert where is not None and where[:2] == (pool.name, 0)
        header = codec.frame_header(passed_on, lambda arr: relay.slot_of(arr)[2])
        fwd = relay.forward(pool.name, 0, [5], header)
        assert fwd is not None and is_forward(fwd) and len(fwd) < 400  # no pixels in it
        assert relay.forward(pool.name, 0, [5], header) is None  # column 5 already holds it
        del got, passed_on
        gc.collect()
        assert pool.busy == 1  # the relay let go, the last consumer holds it now
        assert pool.write(*codec.frame(_frame(2)), [1]) is None
        payload, _release, fwd_header = last.open_forward(fwd, 5)
        out = codec.decode_placed(fwd_header, payload, Image)
        del payload
        assert (out.seq, out.stamp, out.frame) == (7, 2.5, "wrist")
        np.testing.assert_array_equal(out.pixels, first.pixels)
        del out
        gc.collect()
        assert pool.busy == 0
        assert pool.write(*codec.frame(_frame(2)), [1]) is not None
        with pytest.raises(ValueError, match="stale"):
            last.open_forward(fwd, 5)  # the slot holds frame 2 now
    finally:
        pool.close()


def test_arrays_outside_a_pool_slot_are_not_forwarded() -> None:
    codec, reader = Codec(), PoolReader()
    head, parts, size = codec.frame(_frame(1))
    pool = FramePool(size, consumers=1, slots=1)
    try:
        view, _ = reader.open(pool.write(head, parts, size), 0)
        inside = codec.decode(view).pixels
        assert reader.slot_of(inside) is not None
        assert reader.slot_of(inside[1:]) is not None  # a contiguous tail still lies in the slot
        assert reader.slot_of(np.array(inside)) is None  # a copy lies on the heap
        fwd = reader.forward(pool.name, 0, [0], b"header")
        assert fwd is None  # column 0 still holds the slot: never set twice
        forged = b"UMBf" + bytes(80) + b"xx"
        assert is_forward(forged)
        with pytest.raises(ValueError):
            reader.open_forward(forged, 0)
    finally:
        pool.close()


def test_bad_descriptors_are_refused() -> None:
    codec, reader = Codec(), PoolReader()
    pool = FramePool(*codec.frame(_frame(1))[2:], consumers=1)
    try:
        good = pool.write(*codec.frame(_frame(1)))
        assert good is not None
        magic, name, slot, gen, length = struct.unpack("<4s48sIQQ", good)
        forged = [
            struct.pack("<4s48sIQQ", magic, b"../../etc/passwd", slot, gen, length),
            struct.pack("<4s48sIQQ", magic, name, 999, gen, length),
            struct.pack("<4s48sIQQ", magic, name, slot, gen, 1 << 40),
            struct.pack("<4s48sIQQ", magic, name, slot, gen + 7, length),
        ]
        for bad in forged:
            with pytest.raises((ValueError, OSError)):
                reader.open(bad, 0)
        with pytest.raises(ValueError):
            reader.open(good, 3)  # no such consumer
    finally:
        pool.close()


def test_files_of_dead_processes_are_swept_and_markers_name_live_ones() -> None:
    dead = SHM_DIR / f"umbra-pool-{PID_NS}-999999999-{'a' * 16}"
    foreign = SHM_DIR / f"umbra-pool-{PID_NS + 1}-999999999-{'b' * 16}"
    for path in (dead, foreign):
        path.touch()
    try:
        sweep_stale()
        assert not dead.exists()
        assert foreign.exists()  # another pid namespace: its pids cannot be checked from here
    finally:
        foreign.unlink(missing_ok=True)
        dead.unlink(missing_ok=True)
    marker = HostMarker()
    try:
        assert marker_pid(marker.id) == os.getpid()
        assert marker_pid(f"{PID_NS}-123-{'c' * 16}") is None  # no such file here
        assert marker_pid("../../x") is None
    finally:
        marker.close()
    assert marker_pid(marker.id) is None
