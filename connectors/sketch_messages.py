"""Deprecated home of the Active Sketch message types: they live in the sketch domain,
:mod:`modules.sketch.messages`; import them from there.

Kept only so that importers not yet moved keep working; the framework's base layer imports
nothing from here (``tests/test_import_direction.py`` allows this one arrow back, and only here).
"""

from modules.sketch.messages import (
    MacroRequest,
    PtuCommand,
    PtuState,
    SceneObjects,
    SketchBox,
    SketchPrimitive,
    StereoSnapshot,
    ToolPath,
    VcrCommand,
    VcrState,
)

__all__ = [
    "MacroRequest",
    "PtuCommand",
    "PtuState",
    "SceneObjects",
    "SketchBox",
    "SketchPrimitive",
    "StereoSnapshot",
    "ToolPath",
    "VcrCommand",
    "VcrState",
]
