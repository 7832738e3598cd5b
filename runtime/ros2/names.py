"""ROS 2 names as rmw_zenoh puts them on the wire: fully qualified topic names, the ``%``
mangling of liveliness tokens, and DDS type names (``std_msgs/msg/String`` is
``std_msgs::msg::dds_::String_``).

Topic names follow ``rmw_validate_full_topic_name``: absolute (``/`` first), tokens of letters,
digits and underscores separated by single slashes, no token starting with a digit, no trailing
slash, at most :data:`MAX_TOPIC_NAME_LENGTH` characters.
"""

from __future__ import annotations

import re

#: Longest fully qualified topic name rmw accepts (``RMW_TOPIC_MAX_NAME_LENGTH``) [characters].
MAX_TOPIC_NAME_LENGTH = 247
#: What stands for ``/`` inside one chunk of a liveliness token.
SLASH_REPLACEMENT = "%"

_TOKEN = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_MESSAGE_TYPE = re.compile(r"^([A-Za-z][A-Za-z0-9_]*)/msg/([A-Z][A-Za-z0-9]*)$")
_DDS_TYPE = re.compile(r"^([A-Za-z][A-Za-z0-9_]*)::msg::dds_::([A-Z][A-Za-z0-9]*)_$")


def topic_name_problem(name: object) -> str | None:
    """Why ``name`` is not a fully qualified ROS 2 topic name (None when it is one)."""
    if not isinstance(name, str) or not name:
        return f"expected a fully qualified ROS 2 topic name like `/joint_states`, found {name!r}"
    if not name.startswith("/"):
        return f"a ROS 2 topic name must be absolute (start with `/`), found {name!r}"
    if name == "/" or name.endswith("/"):
        return f"a ROS 2 topic name must not end with `/`, found {name!r}"
    if len(name) > MAX_TOPIC_NAME_LENGTH:
        return (
            f"a ROS 2 topic name has at most {MAX_TOPIC_NAME_LENGTH} characters, found {len(name)}"
        )
    for token in name[1:].split("/"):
        if not token:
            return f"a ROS 2 topic name must not contain `//`, found {name!r}"
        if token[0].isdigit():
            return (
                f"a token of a ROS 2 topic name must not start with a digit: {token!r} in {name!r}"
            )
        if not _TOKEN.match(token):
            return (
                f"a ROS 2 topic name holds only letters, digits, `_` and `/`: {token!r} in {name!r}"
            )
    return None


def message_type_problem(ros_type: object) -> str | None:
    """Why ``ros_type`` is not spelled as a ROS 2 message type ``package/msg/Name``."""
    if not isinstance(ros_type, str) or not _MESSAGE_TYPE.match(ros_type):
        return (
            f"expected a ROS 2 message type like `sensor_msgs/msg/JointState`, found {ros_type!r}"
        )
    return None


def mangle(name: str) -> str:
    """``name`` as one chunk of a liveliness token: every ``/`` becomes ``%`` (the empty name,
    as an unset enclave, is ``%`` alone)."""
    return name.replace("/", SLASH_REPLACEMENT) if name else SLASH_REPLACEMENT


def demangle(chunk: str) -> str:
    """The name a liveliness token's chunk stands for (``%chatter`` -> ``/chatter``)."""
    return chunk.replace(SLASH_REPLACEMENT, "/")


def dds_type_name(ros_type: str) -> str:
    """The DDS name of a message type, as rmw_zenoh's keys carry it:
    ``std_msgs/msg/String`` -> ``std_msgs::msg::dds_::String_``."""
    m = _MESSAGE_TYPE.match(ros_type)
    if m is None:
        raise ValueError(message_type_problem(ros_type))
    return f"{m.group(1)}::msg::dds_::{m.group(2)}_"


def ros_type_name(dds_type: str) -> str | None:
    """The ROS 2 name of a DDS message type name (None when ``dds_type`` is not one)."""
    m = _DDS_TYPE.match(dds_type)
    return f"{m.group(1)}/msg/{m.group(2)}" if m else None


def node_name_problem(name: object) -> str | None:
    """Why ``name`` is not a ROS 2 node name (letters, digits, ``_``; not starting with a digit)."""
    if not isinstance(name, str) or not _TOKEN.match(name):
        return f"expected a ROS 2 node name like `umbra_bridge`, found {name!r}"
    return None


def namespace_problem(namespace: object) -> str | None:
    """Why ``namespace`` is not a ROS 2 namespace (``/`` or a fully qualified name)."""
    if namespace == "/":
        return None
    problem = topic_name_problem(namespace)
    return problem.replace("topic name", "namespace") if problem else None
