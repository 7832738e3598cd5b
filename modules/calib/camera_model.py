"""The camera model of the calibration code: pin-hole intrinsics, OpenCV distortion, extrinsics.

A world point ``X`` (metres, in the camera's reference frame: the workcell, the PTU mount, ...)
goes to camera coordinates ``X_cam = R X + d`` (camera frame: x right, y down, z along the optic
axis), to normalized coordinates ``(x, y) = (X_cam[0] / X_cam[2], X_cam[1] / X_cam[2])``, through
the distortion model of :mod:`umbra.modules.calib.distortion` to ``(x_d, y_d)``, and to the pixel
``u = fx x_d + skew y_d + u0``, ``v = fy y_d + v0``. Without distortion this is the camera matrix
``P = K [R | d]`` of Appendix A/B of the Sandia report with
``K = [[fx, skew, u0], [0, fy, v0], [0, 0, 1]]`` (the report's ``fxy`` is ``skew``).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from umbra.modules.calib.distortion import distort_normalized, undistort_normalized_newton
from umbra.modules.calib.rotations import rotation_from_vector, transform, vector_from_rotation

if TYPE_CHECKING:
    from umbra.connectors.messages import CameraModel

FloatArray = NDArray[np.float64]

INTRINSIC_NAMES = ("fx", "fy", "skew", "u0", "v0")
DISTORTION_NAMES = ("k1", "k2", "p1", "p2", "k3")


@dataclass(frozen=True)
class Intrinsics:
    """Pin-hole intrinsics in pixels, in the order of the ``CameraModel`` message's fields: focal
    lengths ``fx``, ``fy``, ``skew`` (the report's fxy), principal point ``u0``, ``v0``, and the
    image size ``width`` x ``height`` they hold for.

    The one intrinsics type of the project: calibration, the servo's features and the simulated
    cameras use it. Nothing is checked here (a fit passes through any values); a user of the
    focal lengths that needs them positive says so where it divides by them.
    """

    fx: float
    fy: float
    skew: float
    u0: float
    v0: float
    width: int = 640
    height: int = 480

    def matrix(self) -> FloatArray:
        """The 3x3 upper-triangular intrinsic matrix ``K``."""
        return np.array(
            [[self.fx, self.skew, self.u0], [0.0, self.fy, self.v0], [0.0, 0.0, 1.0]], dtype=float
        )

    def as_array(self) -> FloatArray:
        """``[fx, fy, skew, u0, v0]`` [px]."""
        return np.array([self.fx, self.fy, self.skew, self.u0, self.v0], dtype=float)

    def normalized_from_pixels(self, pixels: ArrayLike) -> FloatArray:
        """Normalized image coordinates ``(x, y)`` of pixels ``(u, v)`` (shape ``(..., 2)``):
        ``y = (v - v0) / fy``, ``x = (u - u0 - skew y) / fx``."""
        uv = np.asarray(pixels, dtype=float)
        y = (uv[..., 1] - self.v0) / self.fy
        x = (uv[..., 0] - self.u0 - self.skew * y) / self.fx
        return np.stack([x, y], axis=-1)

    def pixels_from_normalized(self, normalized: ArrayLike) -> FloatArray:
        """Pixels ``(u, v)`` of normalized coordinates ``(x, y)`` (shape ``(..., 2)``)."""
        xy = np.asarray(normalized, dtype=float)
        u = self.fx * xy[..., 0] + self.skew * xy[..., 1] + self.u0
        v = self.fy * xy[..., 1] + self.v0
        return np.stack([u, v], axis=-1)

    @classmethod
    def from_matrix(cls, K: ArrayLike, width: int = 640, height: int = 480) -> Intrinsics:
        """The intrinsics of a 3x3 ``K`` (any scale) for an image of ``width`` x ``height``."""
        Km = np.asarray(K, dtype=float)
        Km = Km / Km[2, 2]
        return cls(
            float(Km[0, 0]),
            float(Km[1, 1]),
            float(Km[0, 1]),
            float(Km[0, 2]),
            float(Km[1, 2]),
            width,
            height,
        )

    @classmethod
    def from_array(cls, values: ArrayLike) -> Intrinsics:
        """The intrinsics of ``[fx, fy, skew, u0, v0]`` [px] (the default image size)."""
        fx, fy, skew, u0, v0 = (float(v) for v in np.asarray(values, dtype=float))
        return cls(fx, fy, skew, u0, v0)

    @classmethod
    def of_model(cls, model: CameraModel) -> Intrinsics:
        """The intrinsics a ``CameraModel`` message carries (its distortion and pose aside)."""
        return cls(model.fx, model.fy, model.skew, model.u0, model.v0, model.width, model.height)


def _zero_distortion() -> FloatArray:
    return np.zeros(5)


@dataclass(frozen=True, eq=False)
class PinholeCamera:
    """A calibrated camera: intrinsics, distortion ``(k1, k2, p1, p2, k3)``, extrinsics ``R, d``.

    ``R`` (3x3, det +1) and ``d`` (metres) take reference-frame points into the camera frame.
    """

    intrinsics: Intrinsics
    R: FloatArray = field(default_factory=lambda: np.eye(3))
    d: FloatArray = field(default_factory=lambda: np.zeros(3))
    distortion: FloatArray = field(default_factory=_zero_distortion)

    def __post_init__(self) -> None:
        dist = np.zeros(5)
        given = np.asarray(self.distortion, dtype=float).ravel()
        if given.size not in (0, 4, 5):
            raise ValueError(f"distortion needs 4 or 5 coefficients, got {given.size}")
        dist[: given.size] = given
        object.__setattr__(self, "distortion", dist)
        object.__setattr__(self, "R", np.asarray(self.R, dtype=float).reshape(3, 3))
        object.__setattr__(self, "d", np.asarray(self.d, dtype=float).reshape(3))

    @property
    def K(self) -> FloatArray:
        return self.intrinsics.matrix()

    @property
    def rotation_vector(self) -> FloatArray:
        """Axis-angle vector (radians) of ``R`` (OpenCV's ``rvec``)."""
        return vector_from_rotation(self.R)

    @classmethod
    def from_vectors(
        cls,
        intrinsics: Intrinsics,
        rotation_vector: ArrayLike,
        d: ArrayLike,
        distortion: ArrayLike = (),
    ) -> PinholeCamera:
        return cls(
            intrinsics,
            rotation_from_vector(rotation_vector),
            np.asarray(d),
            np.asarray(distortion, dtype=float),
        )

    def camera_matrix(self) -> FloatArray:
        """``P = K [R | d]`` (ignores distortion)."""
        return self.K @ np.hstack([self.R, self.d[:, None]])

    def centre(self) -> FloatArray:
        """Centre of projection in the reference frame (metres): ``-R^T d``."""
        return -self.R.T @ self.d

    def with_distortion(self, distortion: ArrayLike) -> PinholeCamera:
        return replace(self, distortion=np.asarray(distortion, dtype=float))

    def extrinsic_matrix(self) -> FloatArray:
        """``T_cam_ref``: the 4x4 of ``R, d`` (reference-frame points into the camera frame)."""
        return transform(self.R, self.d)

    def with_extrinsic_matrix(self, T_cam_ref: ArrayLike) -> PinholeCamera:
        """The same intrinsics and distortion with extrinsics from a 4x4 ``T_cam_ref``."""
        T = np.asarray(T_cam_ref, dtype=float)
        return replace(self, R=T[:3, :3], d=T[:3, 3])

    def to_camera_frame(self, points: ArrayLike) -> FloatArray:
        """Reference-frame points ``(..., 3)`` into the camera frame."""
        return np.asarray(points, dtype=float) @ self.R.T + self.d

    def project(self, points: ArrayLike) -> FloatArray:
        """Pixels ``(..., 2)`` of reference-frame points ``(..., 3)``, distortion included."""
        camera_points = self.to_camera_frame(points)
        normalized = camera_points[..., :2] / camera_points[..., 2:3]
        return self.pixels_from_normalized(distort_normalized(normalized, self.distortion))

    def pixels_from_normalized(self, normalized: ArrayLike) -> FloatArray:
        """Apply ``K`` to (distorted or ideal) normalized coordinates."""
        return self.intrinsics.pixels_from_normalized(normalized)

    def normalized_from_pixels(self, pixels: ArrayLike) -> FloatArray:
        """Inverse of :meth:`pixels_from_normalized`."""
        return self.intrinsics.normalized_from_pixels(pixels)

    def ideal_pixels(self, pixels: ArrayLike) -> FloatArray:
        """Measured (distorted) pixels to the pixels of the ideal pin-hole camera ``K [R | d]``."""
        normalized = undistort_normalized_newton(
            self.normalized_from_pixels(pixels), self.distortion
        )
        return self.pixels_from_normalized(normalized)
