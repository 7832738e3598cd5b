"""The graph's static frames: declared once each, no loop among them, joining every pair a
module needs; and every frame a parameter names is one the graph knows."""

from __future__ import annotations

from collections.abc import Mapping

from umbra.connectors.errors import Location
from umbra.connectors.frames import FrameTree
from umbra.runtime.graph.check_report import Report
from umbra.runtime.graph.plan import ModulePlan
from umbra.runtime.graph.spec import GraphSpec
from umbra.runtime.hints import did_you_mean

#: Frames every graph knows without declaring them.
WELL_KNOWN_FRAMES = ("base", "world", "lab", "tool", "flange", "camera")


def static_frames(spec: GraphSpec, error: Report) -> FrameTree:
    """The tree of the graph's ``frames:``, leaving out (and reporting) a pair declared twice or
    one that closes a loop."""
    tree = FrameTree()
    seen: dict[tuple[str, str], Location] = {}
    for f in spec.frames:
        pair = (f.parent, f.child)
        if pair in seen or (f.child, f.parent) in seen:
            error(f.loc, f"frame `{f.parent}->{f.child}` declared twice")
            continue
        if tree.has(f.parent, f.child):
            error(f.loc, f"frame `{f.parent}->{f.child}` closes a loop of static frames")
            continue
        seen[pair] = f.loc
        tree.add(f.parent, f.child, f.T_parent_child)
    return tree


def check_frames(modules: Mapping[str, ModulePlan], tree: FrameTree, error: Report) -> None:
    """Every module's required static frames are joined by ``tree``, and every ``frame`` /
    ``*_frame`` parameter names a known frame (declared, well known, or a port's)."""
    for plan in modules.values():
        missing = [f"{a}->{b}" for a, b in plan.params.required_frames() if not tree.has(a, b)]
        if missing:
            error(
                plan.spec.loc,
                f"module `{plan.name}` ({plan.spec.type}) needs the static frame(s) "
                f"{', '.join(missing)}, which the graph's `frames:` do not join",
                "declare them under `frames:` as `parent->child`",
            )
    known = set(WELL_KNOWN_FRAMES) | tree.names
    for plan in modules.values():
        for decl in [*plan.input_decls.values(), *plan.cls.output_decls().values()]:
            if isinstance(decl.frame, str):
                known.add(decl.frame)
                known.update(decl.frame.split("->"))
    for plan in modules.values():
        for key, value in plan.spec.params.items():
            if not (key == "frame" or key.endswith("_frame")) or not isinstance(value, str):
                continue
            if value and value not in known:
                error(
                    plan.spec.param_val_loc.get(key, plan.spec.params_loc),
                    f"unknown frame `{value}` in parameter `{key}` of `{plan.name}`"
                    f"{did_you_mean(value, sorted(known))}",
                    "declare it under `frames:` as `parent->child`",
                )
