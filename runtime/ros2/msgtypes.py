"""ROS 2 message types from ``rosbags`` (pure Python, no ROS installation): which types exist in
a distribution, their RIHS01 type hashes (REP 2016, the last chunk of rmw_zenoh's keys), their
CDR encoding and their definitions as text (for MCAP's ``ros2msg`` schemas).

One typestore per distribution, built once per process; a mapping names its distribution
(``jazzy`` by default) and every name and hash comes from that distribution's definitions.
"""

from __future__ import annotations

import functools
from typing import Any

from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.store import Typestore

from umbra.runtime.ros2.names import message_type_problem

#: The ROS 2 distributions whose wire format the bridge speaks (RIHS01 hashes, 33-byte
#: attachments: rmw_zenoh on Jazzy, Kilted and Rolling), and the rosbags typestore of each.
DISTROS: dict[str, Stores] = {
    "jazzy": Stores.ROS2_JAZZY,
    "kilted": Stores.ROS2_KILTED,
    "rolling": Stores.LATEST,
}
DEFAULT_DISTRO = "jazzy"


def distro_problem(distro: object) -> str | None:
    """Why ``distro`` is not a distribution the bridge speaks (None when it is one)."""
    if distro not in DISTROS:
        return f"expected a ROS 2 distribution among {', '.join(DISTROS)}, found {distro!r}"
    return None


@functools.cache
def typestore(distro: str = DEFAULT_DISTRO) -> Typestore:
    """The message definitions of ``distro`` (built once per process)."""
    problem = distro_problem(distro)
    if problem:
        raise ValueError(problem)
    return get_typestore(DISTROS[distro])


def known_type_problem(ros_type: object, distro: str = DEFAULT_DISTRO) -> str | None:
    """Why ``ros_type`` is not a message type of ``distro`` (None when it is one)."""
    problem = message_type_problem(ros_type)
    if problem:
        return problem
    if ros_type not in typestore(distro).fielddefs:
        return f"no message type {ros_type!r} in ROS 2 {distro}'s standard interfaces"
    return None


@functools.cache
def type_hash(ros_type: str, distro: str = DEFAULT_DISTRO) -> str:
    """The RIHS01 hash of ``ros_type`` (``RIHS01_`` and 64 hex digits), as rosidl computes it."""
    return typestore(distro).hash_rihs01(ros_type)


def message_class(ros_type: str, distro: str = DEFAULT_DISTRO) -> Any:
    """The rosbags class of ``ros_type`` (a dataclass whose fields are the message's)."""
    return typestore(distro).types[ros_type]


def to_cdr(message: Any, ros_type: str, distro: str = DEFAULT_DISTRO) -> bytes:
    """``message`` in CDR, little-endian, with its 4-byte encapsulation header (what rmw_zenoh
    puts on the wire)."""
    return bytes(typestore(distro).serialize_cdr(message, ros_type))


def from_cdr(payload: bytes, ros_type: str, distro: str = DEFAULT_DISTRO) -> Any:
    """The message that ``payload`` (CDR with its encapsulation header) holds; ValueError when it
    does not hold one of ``ros_type``."""
    try:
        return typestore(distro).deserialize_cdr(payload, ros_type)
    except Exception as exc:  # rosbags raises struct, index and its own errors on bad bytes
        raise ValueError(f"not a CDR {ros_type}: {exc}") from None


def definition_text(ros_type: str, distro: str = DEFAULT_DISTRO) -> str:
    """The ``.msg`` text of ``ros_type`` followed by its dependencies' (``MSG:`` sections), the
    ``ros2msg`` schema encoding of MCAP and rosbag2."""
    text, _ = typestore(distro).generate_msgdef(ros_type, ros_version=2)
    return text
