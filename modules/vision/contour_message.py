"""The Contour message of a polygon and its moment features (vsSnake's output, DigiCam's truth)."""

from __future__ import annotations

import msgspec
import numpy as np
from numpy.typing import ArrayLike

from umbra.connectors.messages import Contour
from umbra.connectors.tracking import SnakeCheck, TrackStatus
from umbra.modules.vision.features import PolygonFeatures


def contour_message(
    vertices: ArrayLike,
    features: PolygonFeatures | None,
    status: TrackStatus,
    reason: str,
    stamp: float,
    offending: ArrayLike | None = None,
    checks: tuple[SnakeCheck, ...] = (),
) -> Contour:
    """A :class:`Contour` of ``vertices`` (N x 2 px) with ``features`` (None: empty centroid and
    axes, zero area and orientation), ``offending`` vertex indices when given, and the codes of
    the failed ``checks``."""
    if features is None:
        centroid, area, orientation, axes = np.zeros(0), 0.0, 0.0, np.zeros(0)
    else:
        centroid = np.array(features.centroid_uv)
        area, orientation = features.area_px2, features.orientation_rad
        axes = np.array([features.major_axis_px, features.minor_axis_px])
    contour = Contour(
        vertices=np.asarray(vertices, dtype=np.float64).reshape(-1, 2),
        centroid=centroid,
        area=area,
        orientation=orientation,
        axes=axes,
        status=status,
        reason=reason,
        checks=checks,
        stamp=stamp,
    )
    if offending is None:
        return contour  # the message's own default (no offending vertex)
    return msgspec.structs.replace(contour, offending=np.asarray(offending).astype(np.int64))
