"""The QoS of a ROS 2 endpoint and its compact form in rmw_zenoh's liveliness tokens.

The compact form lists, separated by ``:`` — reliability, durability, ``history,depth``,
``deadline_s,deadline_ns``, ``lifespan_s,lifespan_ns``, ``liveliness,lease_s,lease_ns`` — and
leaves empty every value equal to rmw_zenoh's default (reliable, volatile, keep-last 42, infinite
durations, automatic liveliness). rclcpp's default profile (depth 10) is ``::,10:,:,:,,``.
Policy numbers are rmw's enums (``RMW_QOS_POLICY_*``).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum


class Reliability(IntEnum):
    RELIABLE = 1
    BEST_EFFORT = 2


class Durability(IntEnum):
    TRANSIENT_LOCAL = 1
    VOLATILE = 2


class History(IntEnum):
    KEEP_LAST = 1
    KEEP_ALL = 2


class Liveliness(IntEnum):
    AUTOMATIC = 1
    MANUAL_BY_TOPIC = 3


#: rmw's infinite duration (``RMW_DURATION_INFINITE``): seconds and nanoseconds.
INFINITE = (9223372036, 854775807)


@dataclass(frozen=True)
class QosProfile:
    """A ROS 2 QoS profile; durations are ``(seconds, nanoseconds)``."""

    reliability: Reliability = Reliability.RELIABLE
    durability: Durability = Durability.VOLATILE
    history: History = History.KEEP_LAST
    depth: int = 42
    deadline: tuple[int, int] = INFINITE
    lifespan: tuple[int, int] = INFINITE
    liveliness: Liveliness = Liveliness.AUTOMATIC
    lease: tuple[int, int] = INFINITE

    def encode(self) -> str:
        """The compact form rmw_zenoh puts in a token (defaults left empty)."""
        d = RMW_ZENOH_DEFAULT

        def v(mine: object, default: object) -> str:
            return "" if mine == default else str(int(mine))  # type: ignore[call-overload]

        return ":".join(
            [
                v(self.reliability, d.reliability),
                v(self.durability, d.durability),
                f"{v(self.history, d.history)},{v(self.depth, d.depth)}",
                f"{v(self.deadline[0], d.deadline[0])},{v(self.deadline[1], d.deadline[1])}",
                f"{v(self.lifespan[0], d.lifespan[0])},{v(self.lifespan[1], d.lifespan[1])}",
                f"{v(self.liveliness, d.liveliness)},{v(self.lease[0], d.lease[0])},"
                f"{v(self.lease[1], d.lease[1])}",
            ]
        )

    @classmethod
    def decode(cls, text: str) -> QosProfile:
        """The profile a token's compact form states; ValueError when it is not one."""
        d = RMW_ZENOH_DEFAULT
        parts = text.split(":")
        if len(parts) != 6:
            raise ValueError(f"expected 6 `:`-separated QoS fields, found {len(parts)} in {text!r}")
        hist, dl, ls, lv = (p.split(",") for p in parts[2:])
        if (len(hist), len(dl), len(ls), len(lv)) != (2, 2, 2, 3):
            raise ValueError(f"expected QoS fields `h,d:s,ns:s,ns:l,s,ns`, found {text!r}")

        def n(chunk: str, default: int) -> int:
            if chunk == "":
                return default
            if not chunk.isdigit():
                raise ValueError(
                    f"expected a non-negative integer in QoS {text!r}, found {chunk!r}"
                )
            return int(chunk)

        return cls(
            reliability=Reliability(n(parts[0], d.reliability)),
            durability=Durability(n(parts[1], d.durability)),
            history=History(n(hist[0], d.history)),
            depth=n(hist[1], d.depth),
            deadline=(n(dl[0], d.deadline[0]), n(dl[1], d.deadline[1])),
            lifespan=(n(ls[0], d.lifespan[0]), n(ls[1], d.lifespan[1])),
            liveliness=Liveliness(n(lv[0], d.liveliness)),
            lease=(n(lv[1], d.lease[0]), n(lv[2], d.lease[1])),
        )


#: rmw_zenoh's default profile: the values a token leaves empty.
RMW_ZENOH_DEFAULT = QosProfile()
#: rclcpp's default for publishers and subscriptions (``rclcpp::QoS(10)``).
ROS_DEFAULT = QosProfile(depth=10)
#: rclcpp's sensor-data profile (``rclcpp::SensorDataQoS``): best effort, depth 5.
SENSOR_DATA = QosProfile(reliability=Reliability.BEST_EFFORT, depth=5)
