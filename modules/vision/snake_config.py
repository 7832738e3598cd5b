"""The snake's user settings, declared once: the vsSnake module and ``umbra snake --set`` both
validate through :class:`SnakeSettings`.

The names are those of :class:`~umbra.modules.vision.snake.SnakeParams` and
:class:`~umbra.modules.vision.sanity.SanityLimits` (their defaults are the settings' defaults),
except that angles a user types are in degrees and say so (``max_rotation_deg``). Every bound,
and every rule between two settings, is in the declaration; :func:`snake_setup` builds the
snake's parameters and limits from validated settings without judging them again.
"""

from __future__ import annotations

from dataclasses import fields
from typing import Any

import numpy as np
from pydantic import model_validator

from umbra.connectors.params import Parameters, ParamProblem, param
from umbra.modules.vision.sanity import SanityLimits
from umbra.modules.vision.snake import SnakeParams
from umbra.modules.vision.transfer import Encoding

#: User-facing limit names that differ from the SanityLimits field, with their conversion.
_DEGREE_LIMITS = {"max_rotation_deg": "max_rotation_rad"}


def setting_defaults() -> dict[str, Any]:
    """Every snake and sanity field name with its default value (angles in degrees)."""
    defaults: dict[str, Any] = {f.name: f.default for f in fields(SnakeParams)}
    for f in fields(SanityLimits):
        defaults[f.name] = f.default
    for user_name, field_name in _DEGREE_LIMITS.items():
        defaults[user_name] = float(np.rad2deg(defaults.pop(field_name)))
    return defaults


_D = setting_defaults()


class SnakeSettings(Parameters):
    """The snake's settings a user may give (vsSnake parameters, ``umbra snake --set``)."""

    k_sigma: float = param(_D["k_sigma"], "color gate radius", unit="sigma", gt=0, tunable=True)
    min_gray: float = param(_D["min_gray"], "darker pixels never count", unit="gray levels", ge=0)
    dim_share: float = param(
        _D["dim_share"],
        "pixels darker than this share of the patch's light on the frame never count (0: off)",
        ge=0,
        lt=1,
    )
    step_px: float = param(
        _D["step_px"], "largest pressure move per iteration", unit="px", gt=0, tunable=True
    )
    tension: float = param(_D["tension"], "smoothing per iteration", ge=0, le=0.5, tunable=True)
    window_radius_px: int = param(
        _D["window_radius_px"], "half-width of the pixel window", unit="px", ge=0, le=64
    )
    min_segment_px: float = param(
        _D["min_segment_px"], "shorter segments trigger resampling", unit="px", gt=0
    )
    max_segment_px: float = param(
        _D["max_segment_px"], "longer segments trigger resampling", unit="px", gt=0
    )
    seed_radius_px: float = param(
        _D["seed_radius_px"], "radius of the point seed circle", unit="px", gt=0
    )
    max_iterations: int = param(
        _D["max_iterations"], "iterations to acquire after a seed", ge=1, le=10_000
    )
    track_iterations: int = param(
        _D["track_iterations"], "iterations per image when tracking", ge=1, le=1_000, tunable=True
    )
    converge_px: float = param(
        _D["converge_px"], "converged when no vertex moves more", unit="px", gt=0
    )
    adapt_rate: float = param(
        _D["adapt_rate"], "color model adaptation per image", ge=0, le=1, tunable=True
    )
    edge_half_length_px: float = param(
        _D["edge_half_length_px"],
        "half-length of the sub-pixel edge profile (0: off)",
        unit="px",
        ge=0,
        le=32,
    )
    corner_turn_deg: float = param(
        _D["corner_turn_deg"], "sharper turns are corners put back", unit="deg", gt=0, le=180
    )
    side_fit_px: float = param(
        _D["side_fit_px"],
        "edge points this close to their side's fitted curve are put on it (0: off)",
        unit="px",
        ge=0,
        le=8,
    )
    side_profiles: int = param(
        _D["side_profiles"],
        "each fitted side is measured again by this many profiles, one a pixel at most (0: off)",
        ge=0,
        le=1_000,
    )
    image_encoding: Encoding = param(
        _D["image_encoding"],
        "how the camera's codes stand for light: linear (raw, machine vision) or srgb (webcams,"
        " phones, most JPEG cameras); the sub-pixel edge is measured on light",
    )
    min_edge_fraction: float = param(
        _D["min_edge_fraction"], "fewer vertices on an edge: failed", ge=0, le=1
    )
    border_margin_px: float = param(
        _D["border_margin_px"], "closer to the image border: failed", unit="px", ge=0
    )
    min_chroma: float = param(
        _D["min_chroma"], "a target colour closer to gray: failed", ge=0, lt=1
    )
    max_unconverged_frames: int = param(
        _D["max_unconverged_frames"], "frames in a row without settling: failed", ge=1
    )
    rectangle_margin: float = param(
        _D["rectangle_margin"], "outer rectangle growth (0.12 = 12 %)", ge=0
    )
    ellipse_scale: float = param(_D["ellipse_scale"], "inner ellipse scale", gt=0, le=1)
    min_area_px2: float = param(_D["min_area_px2"], "smallest area", unit="px²", ge=0)
    max_area_px2: float = param(_D["max_area_px2"], "largest area", unit="px²", gt=0)
    min_aspect: float = param(_D["min_aspect"], "smallest major/minor axis", ge=1)
    max_aspect: float = param(_D["max_aspect"], "largest major/minor axis", ge=1)
    max_centroid_jump_px: float = param(
        _D["max_centroid_jump_px"], "largest centroid move per image", unit="px", gt=0
    )
    max_area_change: float = param(
        _D["max_area_change"], "largest relative area change per image", gt=0
    )
    max_rotation_deg: float = param(
        _D["max_rotation_deg"], "largest rotation per image", unit="deg", gt=0
    )
    max_aspect_change: float = param(
        _D["max_aspect_change"], "largest relative aspect change per image", gt=0
    )
    max_aspect_drift: float = param(
        _D["max_aspect_drift"], "largest aspect change since the seed", gt=0
    )

    @model_validator(mode="after")
    def _ordered(self) -> SnakeSettings:
        """The pairs of bounds are in order (a snake needs room to resample, a contour an area
        and an aspect ratio it can pass)."""
        for low, high, strict in (
            ("min_segment_px", "max_segment_px", True),
            ("min_area_px2", "max_area_px2", True),
            ("min_aspect", "max_aspect", False),
        ):
            a, b = getattr(self, low), getattr(self, high)
            if a > b or (strict and a == b):
                order = "below" if strict else "at most"
                raise ParamProblem(low, f"must be {order} {high} ({b:g}), found {a:g}")
        return self


def snake_setup(settings: SnakeSettings) -> tuple[SnakeParams, SanityLimits]:
    """The snake's parameters and sanity limits from validated ``settings`` (degrees become
    radians; names the settings do not hold keep their defaults)."""
    values = {name: getattr(settings, name) for name in SnakeSettings.model_fields}
    snake_names = {f.name for f in fields(SnakeParams)}
    snake_args = {k: v for k, v in values.items() if k in snake_names}
    limit_args = {k: v for k, v in values.items() if k not in snake_names}
    for user_name, field_name in _DEGREE_LIMITS.items():
        limit_args[field_name] = float(np.deg2rad(limit_args.pop(user_name)))
    return SnakeParams(**snake_args), SanityLimits(**limit_args)
