"""Reasons in an operator's words: the graph's modules give exact, developer-grade reasons
("no colour edge under 100% of the contour (featureless image); area changed -63% in one
frame"); the station shows each in a few plain words, the exact text one click away. Pure.
"""

from __future__ import annotations

#: (fragment of a module's reason, what the operator reads), first match wins per clause
_RULES: tuple[tuple[str, str], ...] = (
    ("no colour edge", "the tracker lost the patch's edge"),
    ("area changed", "the patch's size jumped"),
    ("centroid jumped", "the patch jumped in the image"),
    ("rotated", "the patch turned too fast"),
    ("aspect ratio", "the patch's shape changed"),
    ("outside the outer rectangle", "the outline spilled past the patch"),
    ("inside the inner ellipse", "the outline caved into the patch"),
    ("px² below the minimum", "the patch looks too small"),
    ("px² above the maximum", "the patch looks too large"),
    ("vertices (need", "the outline collapsed"),
    ("identical", "the camera's picture froze"),
    ("frozen", "the camera's picture froze"),
    ("contour is", "the tracker's outline came too late"),
    ("snake has no contour", "no patch seeded yet: click the patch"),
    ("no contour from the snake", "the tracker sends nothing"),
    ("cannot be dated", "the camera data cannot be dated"),
    ("command made from sensor data", "the camera data behind the command is too old"),
    ("no new command", "commands stopped arriving in time"),
    ("command producer is gone", "the vision process is gone"),
    ("vision process is gone", "the vision process is gone"),
    ("no command received yet", "no command yet"),
    ("halted by", "the arm's drives stopped it"),
)

#: prefixes that only say where a reason came from
_PREFIXES = (
    "assistance requested: ",
    "operator assistance requested (",
    "snake failure: ",
    "stopped without a grasp: ",
)


def plain_reason(reason: str) -> str:
    """``reason`` in plain words: each clause (``;``-separated) mapped once, in order; a clause
    no rule knows is kept as it is. "" for "" ."""
    text = reason.strip()
    for prefix in _PREFIXES:
        if text.startswith(prefix):
            text = text[len(prefix) :].rstrip(")")
    words: list[str] = []
    for clause in (c.strip() for c in text.split(";")):
        if not clause:
            continue
        said = next((plain for fragment, plain in _RULES if fragment in clause), clause)
        if said not in words:
            words.append(said)
    return "; ".join(words)
