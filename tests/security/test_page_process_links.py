"""The pages in a process of their own (`ui`): everything they read crosses a link, so every
link into `ui` in the shipped graphs must carry its largest legitimate sample (a stereo snapshot
holds both cameras' frames: the default bound of 256 KiB refused every one)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from umbra.connectors.codec import Codec
from umbra.connectors.sketch_messages import StereoSnapshot
from umbra.runtime.graph.check import load_graph
from umbra.runtime.links.bounds import max_sample_bytes

REPO = Path(__file__).resolve().parents[2]


def test_a_stereo_snapshot_of_two_720p_frames_fits_its_link() -> None:
    frame = np.zeros((720, 1280, 3), np.uint8)
    snap = StereoSnapshot(
        snapshot_id="snap1", image_a=frame, image_b=frame, K_a=np.eye(3), K_b=np.eye(3)
    )
    size = len(Codec().encode(snap))
    assert size > 256 * 1024  # more than the bound of a type without images
    assert size <= max_sample_bytes(StereoSnapshot)


@pytest.mark.parametrize("graph", ["tool_pickup", "tool_pickup_3d", "active_sketch_page"])
def test_the_shipped_graphs_put_their_pages_in_ui(graph: str) -> None:
    plan = load_graph(str(REPO / "graphs" / f"{graph}.yaml"))
    pages = {
        name for name, m in plan.modules.items() if m.cls.TYPE in ("OperatorConsole", "SketchPage")
    }
    assert pages and {plan.modules[n].process for n in pages} == {"ui"}
    assert {m.process for n, m in plan.modules.items() if n not in pages} <= {"umbra", "smart"}
