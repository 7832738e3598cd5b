"""Deprecated name of :mod:`modules.geometry.mount_offset` (the math moved to the geometry
layer, which calibration and vision both build on); import it from there."""

from modules.geometry.mount_offset import offset_mount, offset_transform

__all__ = ["offset_mount", "offset_transform"]
