"""The transform tree a viewer builds from a recording: every frame's parents, read with the
official Foxglove classes from each ``FrameTransform`` and ``FrameTransforms`` channel."""

from __future__ import annotations

from pathlib import Path

from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from mcap.reader import make_reader


def frame_parents(path: Path) -> dict[str, set[str]]:
    """Each child frame of the recording and the parents it was given."""
    parents: dict[str, set[str]] = {}
    with open(path, "rb") as f:
        for schema, _c, msg in make_reader(f).iter_messages():
            if schema is None:
                continue
            if schema.name == "foxglove.FrameTransforms":
                found = list(FrameTransforms.FromString(msg.data).transforms)
            elif schema.name == "foxglove.FrameTransform":
                found = [FrameTransform.FromString(msg.data)]
            else:
                continue
            for t in found:
                parents.setdefault(t.child_frame_id, set()).add(t.parent_frame_id)
    return parents


def assert_one_tree(path: Path, root: str) -> set[str]:
    """Every frame of the recording has one parent and hangs from ``root``; returns the frames."""
    parents = frame_parents(path)
    assert all(len(p) == 1 for p in parents.values()), parents
    parent = {child: next(iter(p)) for child, p in parents.items()}
    for frame in parent:
        top, hops = frame, 0
        while top in parent and hops <= len(parent):
            top, hops = parent[top], hops + 1
        assert top == root, f"{frame} hangs from {top}, not {root}"
    return set(parent)
