"""User-facing snake settings: one flat set of names for the vsSnake module and ``umbra snake``.

The names are those of :class:`~umbra.modules.vision.snake.SnakeParams` and
:class:`~umbra.modules.vision.sanity.SanityLimits`, except that angles a user types are in degrees
and say so (``max_rotation_deg``). :func:`settings_from` validates and converts once.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import fields
from typing import Any

import numpy as np

from umbra.modules.vision.sanity import SanityLimits
from umbra.modules.vision.snake import SnakeParams

#: User-facing limit names that differ from the SanityLimits field, with their conversion.
_DEGREE_LIMITS = {"max_rotation_deg": "max_rotation_rad"}


#: Largest iteration counts a user may ask for (work per image stays bounded).
_MOST = {
    "max_iterations": 10_000,
    "track_iterations": 1_000,
    "max_vertices": 10_000,
    "vertex_budget": 10_000,
    "seed_vertices": 1_000,
    "window_radius_px": 64,
}


class SettingsError(ValueError):
    """A snake setting has an unknown name or a bad value."""


def setting_defaults() -> dict[str, Any]:
    """Every setting name with its default value (angles in degrees)."""
    defaults: dict[str, Any] = {f.name: f.default for f in fields(SnakeParams)}
    for f in fields(SanityLimits):
        defaults[f.name] = f.default
    for user_name, field_name in _DEGREE_LIMITS.items():
        defaults[user_name] = float(np.rad2deg(defaults.pop(field_name)))
    return defaults


def _convert(name: str, value: Any, default: Any) -> Any:
    if isinstance(default, bool) or isinstance(value, bool):
        raise SettingsError(f"snake setting `{name}` must be a number, got {value!r}")
    if isinstance(default, int):
        try:
            number = float(value) if isinstance(value, int | float | str) else None
        except (ValueError, OverflowError):
            number = None
        if number is None or not number.is_integer():
            raise SettingsError(f"snake setting `{name}` must be an integer, got {value!r:.40}")
        if not 0 <= number <= _MOST.get(name, 1e9):
            raise SettingsError(
                f"snake setting `{name}` must be from 0 to {_MOST.get(name, 1e9):g}, got {value!r}"
            )
        return int(number)
    try:
        return float(value)
    except (TypeError, ValueError, OverflowError):
        raise SettingsError(f"snake setting `{name}` must be a number, got {value!r:.40}") from None


def settings_from(values: Mapping[str, Any]) -> tuple[SnakeParams, SanityLimits]:
    """Snake parameters and sanity limits from user settings (missing names keep defaults)."""
    defaults = setting_defaults()
    unknown = sorted(set(values) - set(defaults))
    if unknown:
        raise SettingsError(
            f"unknown snake setting `{unknown[0]}` (known: {', '.join(sorted(defaults))})"
        )
    converted = {name: _convert(name, v, defaults[name]) for name, v in values.items()}
    snake_names = {f.name for f in fields(SnakeParams)}
    snake_args = {k: v for k, v in converted.items() if k in snake_names}
    limit_args = {k: v for k, v in converted.items() if k not in snake_names}
    for user_name, field_name in _DEGREE_LIMITS.items():
        if user_name in limit_args:
            limit_args[field_name] = float(np.deg2rad(limit_args.pop(user_name)))
    try:
        return SnakeParams(**snake_args), SanityLimits(**limit_args)
    except ValueError as exc:
        raise SettingsError(str(exc)) from None
