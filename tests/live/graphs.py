"""Small graphs for the live server's tests (checked as a graph file is)."""

from __future__ import annotations

from umbra.connectors.access.door import Connections
from umbra.runtime.graph.check import check_text
from umbra.runtime.graph.plan import GraphPlan
from umbra.runtime.live.parameters import ParameterTable
from umbra.runtime.live.viewer_server import ViewerServer

#: A scalar scaled by a Gain (tunable gain and bias) and a twist through REG_VEL (a safety
#: guard: none of its parameters is tunable), all in one process.
SMALL = """
graph: small
clock: real
modules:
  src: {type: Constant, rate: 50, params: {value: 2.0}}
  servo: {type: Gain, params: {gain: 0.5}}
  jog: {type: TwistSource, rate: 50}
  guard: {type: REG_VEL, rate: 50}
connections:
  - src.output -> servo.input
  - jog.twist -> guard.command
"""


def small_plan() -> GraphPlan:
    return check_text(SMALL, "small.yaml")


#: The access token of the live servers the tests serve the small plan with.
TOKEN = "t0ken-of-this-run-0123456789"


def small_viewer_server(connections: Connections | None = None) -> ViewerServer:
    """A live server of the small plan on a free loopback port, behind :data:`TOKEN` (with the
    door's connection table ``connections``, default: its own)."""
    return ViewerServer(
        name="test",
        host="127.0.0.1",
        port=0,
        token=TOKEN,
        origins=[],
        parameters=ParameterTable(small_plan()),
        connections=connections,
    )
