"""What a contour tracker says of its contour: its status and, when it failed, which checks.

A :class:`~umbra.connectors.messages.Contour` carries both: ``status`` (:class:`TrackStatus`) and
``checks`` (the :class:`SnakeCheck` codes that failed, in the order found); its ``reason`` keeps
the exact text with the figures ("area changed -63% in one frame"). vsServo passes the codes on in
its state, and the station shows each code's words. The checks are run in
``umbra.modules.vision.sanity`` (shape), ``umbra.modules.vision.tracker`` (the snake itself) and
``umbra.modules.vision.vs_snake`` (the images).
"""

from __future__ import annotations

from umbra.connectors.reasons import Code, Worded


class TrackStatus(Code):
    """A contour's status: on the target, failed (checks say why), or idle (not seeded)."""

    TRACKING = "tracking"
    FAILED = "failed"
    IDLE = "idle"


class SnakeCheck(Worded):
    """A tracker check that failed, with the operator's words."""

    # shape checks (umbra.modules.vision.sanity)
    TOO_FEW_VERTICES = "too_few_vertices", "the outline collapsed"
    ZERO_AREA = "zero_area", "the outline collapsed"
    AREA_BELOW_MIN = "area_below_min", "the patch looks too small"
    AREA_ABOVE_MAX = "area_above_max", "the patch looks too large"
    ASPECT_OUT_OF_BOUNDS = "aspect_out_of_bounds", "the patch's shape changed"
    OUTSIDE_RECTANGLE = "outside_rectangle", "the outline spilled past the patch"
    INSIDE_ELLIPSE = "inside_ellipse", "the outline caved into the patch"
    CENTROID_JUMP = "centroid_jump", "the patch jumped in the image"
    AREA_CHANGE = "area_change", "the patch's size jumped"
    ROTATION = "rotation", "the patch turned too fast"
    ASPECT_CHANGE = "aspect_change", "the patch's shape changed"
    ASPECT_DRIFT = "aspect_drift", "the patch's shape changed"
    # the snake itself (umbra.modules.vision.tracker)
    GRAY_TARGET = "gray_target", "the patch's colour cannot be told from gray"
    SNAKE_COLLAPSED = "snake_collapsed", "the tracker lost the patch's colour"
    NO_EDGE = "no_edge", "the tracker lost the patch's edge"
    TOUCHES_BORDER = "touches_border", "the patch is cut by the image's border"
    NOT_CONVERGED = "not_converged", "the tracker did not settle on the patch"
    # the images (umbra.modules.vision.vs_snake)
    STALE_IMAGE = "stale_image", "the camera stopped sending new pictures"
    GRAYSCALE_IMAGE = "grayscale_image", "the camera sends no colour"
    CAMERA_FROZEN = "camera_frozen", "the camera's picture froze"
