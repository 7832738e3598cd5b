"""Small graphs for the live server's tests (checked as a graph file is)."""

from __future__ import annotations

from umbra.runtime.graph.check import check_text
from umbra.runtime.graph.plan import GraphPlan

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
