"""The graph file's ``ros2:`` section (``umbra.runtime.graph.spec_ros2``): its shape, the topic
names and the message types, each problem at its YAML node. Whether a port exists and has a
conversion to or from the named type is the checker's (``umbra.runtime.graph.check_ros2``)."""

from __future__ import annotations

from typing import Any

from umbra.runtime.graph.located_yaml import YMap
from umbra.runtime.graph.names import endpoint_problem
from umbra.runtime.graph.parse_base import ParserBase, _kind
from umbra.runtime.graph.spec_ros2 import Ros2PortSpec, Ros2Section
from umbra.runtime.ros2.names import node_name_problem, topic_name_problem

SECTION_KEYS = ("domain", "router", "node", "distro", "out", "in")
PORT_KEYS = (
    "topic",
    "type",
    "frame_id",
    "gripper_joint",
    "status_name",
    "clock_error_s",
    "max_transport_age_s",
    "qos",
    "joints",
)
#: Option keys of a port that only an ``in`` (or only an ``out``) mapping takes.
IN_ONLY = ("clock_error_s", "max_transport_age_s", "joints")
OUT_ONLY = ("status_name",)


class Ros2Parser(ParserBase):
    """``ros2:``."""

    def ros2(self, doc: YMap) -> Ros2Section:
        if "ros2" not in doc:
            return Ros2Section()
        from umbra.runtime.ros2.bridge import MAX_DOMAIN  # zenoh, rosbags: with a `ros2:` only
        from umbra.runtime.ros2.msgtypes import distro_problem

        section = self.expect_map(doc["ros2"], doc.val_loc["ros2"], "`ros2`")
        if section is None:
            return Ros2Section()
        self.unknown_keys(section, SECTION_KEYS, "`ros2`")
        out = Ros2Section(loc=section.loc)
        if "domain" in section:
            domain = section["domain"]
            if (
                isinstance(domain, bool)
                or not isinstance(domain, int)
                or not 0 <= domain <= (MAX_DOMAIN)
            ):
                self.error(
                    section.val_loc["domain"],
                    f"`ros2.domain` must be a ROS 2 domain id 0..{MAX_DOMAIN}, found "
                    f"{_kind(domain)}",
                )
            else:
                out.domain = domain
        problem: str | None  # why a setting cannot be; empty or None when it can
        if "router" in section:
            router = section["router"]
            problem = endpoint_problem(router)
            if problem:
                self.error(section.val_loc["router"], f"`ros2.router`: {problem}")
            else:
                out.router = router
        if "node" in section:
            node = section["node"]
            problem = node_name_problem(node)
            if problem:
                self.error(section.val_loc["node"], f"`ros2.node`: {problem}")
            else:
                out.node = node
        if "distro" in section:
            problem = distro_problem(section["distro"])
            if problem:
                self.error(section.val_loc["distro"], f"`ros2.distro`: {problem}")
            else:
                out.distro = section["distro"]
        for direction in ("out", "in"):
            if direction in section:
                ports = self.expect_map(
                    section[direction], section.val_loc[direction], f"`ros2.{direction}`"
                )
                if ports is None:
                    continue
                for key, body in ports.items():
                    port = self._port(ports, key, body, direction, out.distro)
                    if port is not None:
                        out.ports.append(port)
        return out

    def _port(
        self, ports: YMap, key: Any, body: Any, direction: str, distro: str
    ) -> Ros2PortSpec | None:
        from umbra.runtime.ros2.msgtypes import known_type_problem

        where = ports.key_loc[key]
        module, dot, port = str(key).partition(".")
        if not isinstance(key, str) or not dot or not module or not port:
            self.error(
                where, f"`ros2.{direction}` maps `module.port` to a topic, found {_kind(key)}"
            )
            return None
        body = self.expect_map(body, ports.val_loc[key], f"`ros2.{direction}.{key}`")
        if body is None:
            return None
        self.unknown_keys(body, PORT_KEYS, f"`ros2.{direction}.{key}`")
        wrong = IN_ONLY if direction == "out" else OUT_ONLY
        for name in wrong:
            if name in body:
                other = "in" if direction == "out" else "out"
                self.error(body.key_loc[name], f"`{name}` is for `ros2.{other}` mappings only")
        ok = True
        for name in ("topic", "type"):
            if name not in body:
                self.error(body.loc, f"`ros2.{direction}.{key}`: missing `{name}`")
                ok = False
        if not ok:
            return None
        problem = topic_name_problem(body["topic"])
        if problem:
            self.error(body.val_loc["topic"], problem)
            ok = False
        problem = known_type_problem(body["type"], distro)
        if problem:
            self.error(body.val_loc["type"], problem)
            ok = False
        if not ok:
            return None
        options = {k: v for k, v in body.items() if k not in ("topic", "type")}
        return Ros2PortSpec(
            module=module,
            port=port,
            direction=direction,
            topic=body["topic"],
            ros_type=body["type"],
            loc=where,
            options=options,
            field_loc={k: body.val_loc[k] for k in body},
        )
