"""The attachment rmw_zenoh puts on every sample (Jazzy, Kilted, Rolling): 33 bytes,

======  =====  ==========================================================
offset  bytes  field
======  =====  ==========================================================
0       8      sequence number, int64 little-endian (1, 2, 3... per publisher)
8       8      source timestamp, int64 little-endian, ns since the UNIX epoch (CLOCK_REALTIME)
16      1      length of the GID (16)
17      16     the publisher's GID
======  =====  ==========================================================

(zenoh's ``ext::Serializer`` of ``int64, int64, std::array<uint8_t, 16>``: the array's length is
a LEB128 varint, one byte for 16).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

#: Length of a GID on the wire (``RMW_GID_STORAGE_SIZE`` since Iron) [bytes].
GID_BYTES = 16
#: Length of an attachment [bytes].
ATTACHMENT_BYTES = 8 + 8 + 1 + GID_BYTES
_LAYOUT = struct.Struct(f"<qqB{GID_BYTES}s")


@dataclass(frozen=True)
class Attachment:
    """What a sample's attachment says: ``seq``, ``stamp_ns`` [ns since the epoch] and ``gid``."""

    seq: int
    stamp_ns: int
    gid: bytes

    def encode(self) -> bytes:
        """The 33 bytes of this attachment."""
        if len(self.gid) != GID_BYTES:
            raise ValueError(f"expected a {GID_BYTES}-byte GID, found {len(self.gid)} bytes")
        return _LAYOUT.pack(self.seq, self.stamp_ns, GID_BYTES, self.gid)

    @classmethod
    def decode(cls, data: bytes | None) -> Attachment:
        """The attachment ``data`` holds; ValueError (saying what was found) when it is not one."""
        if data is None:
            raise ValueError("expected an rmw_zenoh attachment, found none")
        if len(data) != ATTACHMENT_BYTES:
            raise ValueError(
                f"expected a {ATTACHMENT_BYTES}-byte rmw_zenoh attachment, found {len(data)} bytes"
            )
        seq, stamp_ns, gid_len, gid = _LAYOUT.unpack(data)
        if gid_len != GID_BYTES:
            raise ValueError(f"expected a GID length byte of {GID_BYTES}, found {gid_len}")
        return cls(seq=seq, stamp_ns=stamp_ns, gid=gid)
