"""Requests sent once per action cross processes on ordered, lossless links (events): a zoom
request or Sketch's reply to a command that zenoh dropped under congestion was never sent again
(the likely cause of a CI run in which camera a stayed at zoom 0 while camera b zoomed to the
script's 0.3)."""

from __future__ import annotations

from pathlib import Path

import pytest

from umbra.runtime.graph.check import load_graph

GRAPHS = Path(__file__).resolve().parents[2] / "graphs"


@pytest.mark.parametrize(
    ("graph", "connections"),
    [
        (
            "active_sketch_page.yaml",
            [
                "sketch.zoom_a -> sony_left.zoom_command",
                "sketch.zoom_b -> sony_right.zoom_command",
                "sketch.status ~> operator.sketch_status",
                "sketch.status ~> page.sketch_status",
            ],
        ),
        (
            "active_sketch.yaml",
            ["sketch.zoom_a -> sony_left.zoom_command", "sketch.zoom_b -> sony_right.zoom_command"],
        ),
    ],
)
def test_one_shot_requests_and_replies_cross_processes_losslessly(
    graph: str, connections: list[str]
) -> None:
    plan = load_graph(str(GRAPHS / graph))
    policy = {str(link.connection): link.reliable for link in plan.links}
    for connection in connections:
        if connection not in policy:  # in one process: nothing to lose
            continue
        assert policy[connection], f"{graph}: {connection} is latest-only, not events"
    assert any(c in policy for c in connections), f"{graph}: none of them crosses processes"
