"""Errors of the calibration math: bad input geometry that no algorithm can fix."""

from __future__ import annotations


class CalibrationError(ValueError):
    """Calibration data cannot give the quantity asked for; the message says why and what helps."""


class DegenerateGeometryError(CalibrationError):
    """Too few points, coplanar points, or a configuration with no unique solution."""


class NotConvergedError(CalibrationError):
    """An iterative solver did not converge from the initial guess it was given."""
