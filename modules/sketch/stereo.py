"""A calibrated stereo pair frozen at a snapshot: epipolar constraint and triangulation with
covariance.

Frames: the world is the snapshot's ``frame`` (``base``); each camera looks along +z, x right,
y down. Pixels handed in and out are the pixels the images show (distorted by each camera's
lens); the geometry is done on ideal pin-hole pixels (undistorted with
:func:`umbra.modules.calib.distortion.undistort_points`) and converted back.

Uncertainty (:class:`StereoNoise`) is first order: the Jacobian of the triangulated point with
respect to the four pixel coordinates and to each camera's calibration (rotation, translation,
focal length, principal point) is taken by central differences and the covariance is
``J diag(sigma^2) J^T`` [m²]. :meth:`StereoPair.triangulate_constrained` differentiates the
whole sketch step: the operator's clicks (both images, as clicked), the move of the right-hand
click onto the epipolar line, then triangulation, for all vertices of a primitive at once; its
joint covariance holds the correlation the vertices share through the calibration, which a
derived quantity (a box centre, a line direction) needs. A right-hand vertex may be given the
spread of where the operator believes it is (wider along a featureless edge than across it:
:mod:`umbra.modules.sketch.depth_check`); the operator then leaves its handle at the spot of its
epipolar line that agrees best with that belief.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from umbra.connectors.sketch_messages import StereoSnapshot
from umbra.modules.calib.distortion import distort_points, undistort_points
from umbra.modules.geometry.rays import epipolar_line, line_distance, triangulate_pixels

FloatArray = NDArray[np.float64]
#: A constrained triangulation: points (n, 3) m, joint covariance (3n, 3n) m², gaps (n,) m.
_Vertices = tuple[FloatArray, FloatArray, FloatArray]


@dataclass(frozen=True)
class StereoNoise:
    """One-sigma errors behind a triangulated point.

    Attributes:
        pixel_px: the operator's placement error per image coordinate (px).
        rotation_rad: each camera's orientation error about each axis (rad).
        translation_m: each camera's position error along each axis (m).
        focal_rel: relative error of each camera's focal lengths (1).
        principal_px: error of each camera's principal point per coordinate (px).
        handle_px: the operator's error placing a handle along a featureless edge (px): where
            on the edge "the same point" is, judged by eye; it sets a vertex's depth when the
            edge runs along the epipolar lines (:mod:`umbra.modules.sketch.depth_check`).
    """

    pixel_px: float = 0.5
    rotation_rad: float = 2e-4
    translation_m: float = 2e-4
    focal_rel: float = 2e-3
    principal_px: float = 1.0
    handle_px: float = 20.0

    def __post_init__(self) -> None:
        values = (
            self.pixel_px,
            self.rotation_rad,
            self.translation_m,
            self.focal_rel,
            self.principal_px,
            self.handle_px,
        )
        if not all(np.isfinite(v) and v >= 0 for v in values):
            raise ValueError(f"stereo noise sigmas must be finite and >= 0, got {self}")


@dataclass(frozen=True)
class _Camera:
    K: FloatArray
    dist: FloatArray
    T_base_camera: FloatArray

    def matrix(self) -> FloatArray:
        T_camera_base = np.linalg.inv(self.T_base_camera)
        return self.K @ T_camera_base[:3, :]

    def perturbed(self, delta: FloatArray) -> _Camera:
        """The camera with ``delta`` = [rotvec(3), translation(3), focal_rel, du0, dv0] applied
        (rotation and translation in the camera's own frame)."""
        from scipy.spatial.transform import Rotation

        T = self.T_base_camera.copy()
        T[:3, :3] = T[:3, :3] @ Rotation.from_rotvec(delta[:3]).as_matrix()
        T[:3, 3] = T[:3, 3] + self.T_base_camera[:3, :3] @ delta[3:6]
        K = self.K.copy()
        K[0, 0] *= 1.0 + delta[6]
        K[1, 1] *= 1.0 + delta[6]
        K[0, 2] += delta[7]
        K[1, 2] += delta[8]
        return _Camera(K, self.dist, T)


class StereoPair:
    """Cameras a (left) and b (right) of one snapshot (world frame = the snapshot's ``frame``)."""

    def __init__(
        self,
        K_a: ArrayLike,
        T_base_camera_a: ArrayLike,
        K_b: ArrayLike,
        T_base_camera_b: ArrayLike,
        dist_a: ArrayLike = (0, 0, 0, 0, 0),
        dist_b: ArrayLike = (0, 0, 0, 0, 0),
    ) -> None:
        self._a = _Camera(_f(K_a, (3, 3)), _f(dist_a, (5,)), _f(T_base_camera_a, (4, 4)))
        self._b = _Camera(_f(K_b, (3, 3)), _f(dist_b, (5,)), _f(T_base_camera_b, (4, 4)))
        self.P_a = self._a.matrix()
        self.P_b = self._b.matrix()
        #: the last joint covariance computed, by its clicks and noise (a box built from a
        #: primitive just placed asks for the same one)
        self._constrained: tuple[tuple[object, ...], _Vertices] | None = None

    @classmethod
    def from_snapshot(cls, snap: StereoSnapshot) -> StereoPair:
        """The pair as it was when ``snap`` was taken (zoom and PTU angles included)."""
        return cls(
            snap.K_a, snap.T_base_camera_a, snap.K_b, snap.T_base_camera_b, snap.dist_a, snap.dist_b
        )

    # -- pixels -------------------------------------------------------------------------------
    def ideal(self, side: str, pixels: ArrayLike) -> FloatArray:
        """Image pixels of camera ``side`` to ideal pin-hole pixels."""
        cam = self._cam(side)
        uv = np.asarray(pixels, dtype=float)
        if not np.any(cam.dist):
            return uv
        return undistort_points(uv, cam.K, cam.dist)

    def shown(self, side: str, ideal_pixels: ArrayLike) -> FloatArray:
        """Ideal pin-hole pixels of camera ``side`` to the pixels its image shows."""
        cam = self._cam(side)
        uv = np.asarray(ideal_pixels, dtype=float)
        if not np.any(cam.dist):
            return uv
        return distort_points(uv, cam.K, cam.dist)

    def project(self, side: str, points_base: ArrayLike) -> FloatArray:
        """Image pixels (shown) of 3-D points (m, base) in camera ``side``."""
        P = self.P_a if side == "a" else self.P_b
        X = np.asarray(points_base, dtype=float)
        h = np.concatenate([X, np.ones((*X.shape[:-1], 1))], axis=-1) @ P.T
        return self.shown(side, h[..., :2] / h[..., 2:3])

    # -- epipolar geometry ------------------------------------------------------------------
    def epipolar_line_b(self, pixel_a: ArrayLike) -> FloatArray:
        """The epipolar line ``(l1, l2, l3)`` (ideal pixels of image b, unit normal) of a pixel of
        image a."""
        return epipolar_line(self.P_a, self.P_b, self.ideal("a", pixel_a))

    def constrain_b(
        self, pixel_a: ArrayLike, pixel_b: ArrayLike, spread: ArrayLike | None = None
    ) -> FloatArray:
        """``pixel_b`` moved onto the epipolar line of ``pixel_a`` (the nearest point of it, in
        ideal pixels): the report's constraint on the right-hand vertex. Shapes (2,) or (m, 2).

        With ``spread`` ((2, 2) or (m, 2, 2), px², positive semi-definite, not degenerate
        across the line), "nearest" is in the metric of that covariance: the point of the line
        most consistent with a belief ``pixel_b`` that has that spread (the identity: the
        perpendicular foot)."""
        line = self.epipolar_line_b(pixel_a)
        ideal_b = self.ideal("b", pixel_b)
        off = line_distance(line, ideal_b)
        normal = line[..., :2]
        if spread is None:
            return self.shown("b", ideal_b - off[..., None] * normal)
        S = np.asarray(spread, dtype=float)
        step = np.einsum("...ij,...j->...i", S, np.broadcast_to(normal, S.shape[:-1]))
        step = step / np.sum(step * normal, axis=-1, keepdims=True)
        return self.shown("b", ideal_b - off[..., None] * step)

    def epipolar_direction_b(self, pixel_a: ArrayLike, pixel_b: ArrayLike) -> FloatArray:
        """Unit direction(s) (image-b pixels as shown) of the epipolar curve of ``pixel_a`` at
        ``pixel_b`` (on or near it). Shapes (2,) or (m, 2)."""
        line = self.epipolar_line_b(pixel_a)
        along = line[..., :2] @ np.array([[0.0, 1.0], [-1.0, 0.0]])  # (l1, l2) turned 90 deg
        ideal_b = self.ideal("b", pixel_b)
        step = 0.5 * along
        d = self.shown("b", ideal_b + step) - self.shown("b", ideal_b - step)
        return d / np.linalg.norm(d, axis=-1, keepdims=True)

    def epipolar_error_px(self, pixel_a: ArrayLike, pixel_b: ArrayLike) -> FloatArray:
        """Distance (ideal px) of ``pixel_b`` from the epipolar line of ``pixel_a``."""
        return np.abs(line_distance(self.epipolar_line_b(pixel_a), self.ideal("b", pixel_b)))

    def epipolar_segment_b(
        self, pixel_a: ArrayLike, depth_range_m: tuple[float, float] = (0.2, 5.0)
    ) -> FloatArray:
        """Two image-b pixels (shown) bounding the epipolar line of ``pixel_a`` between depths
        ``depth_range_m`` along camera a's ray (for drawing the line)."""
        ideal_a = self.ideal("a", pixel_a)
        ray_cam = np.linalg.solve(self._a.K, np.append(ideal_a, 1.0))
        T = self._a.T_base_camera
        points = [T[:3, :3] @ (ray_cam * d) + T[:3, 3] for d in depth_range_m]
        return self.project("b", np.stack(points))

    def epipolar_curve_b(
        self,
        pixel_a: ArrayLike,
        size_b: tuple[int, int],
        samples: int = 4000,
        spacing_px: float = 4.0,
    ) -> FloatArray:
        """The epipolar curve of an image-a pixel in image b: the pixels image b shows (lens
        distortion included, so a curve, not a line) of the points along camera a's ray, from
        5 cm in front of it to 10 km, inside the ``size_b = (width, height)`` image. Points
        where b's lens model folds over (no undistortion back to the same ray) are left out.
        ``(m, 2)`` pixels in order along the ray, about ``spacing_px`` apart (``m`` may be 0)."""
        ideal_a = self.ideal("a", np.asarray(pixel_a, dtype=float).reshape(2))
        if not np.all(np.isfinite(ideal_a)):
            return np.zeros((0, 2))
        ray_cam = np.linalg.solve(self._a.K, np.append(ideal_a, 1.0))
        T = self._a.T_base_camera
        inverse_depth = np.linspace(1.0 / 0.05, 1e-4, samples)
        points = (T[:3, :3] @ (ray_cam[:, None] / inverse_depth)).T + T[:3, 3]
        T_b = np.linalg.inv(self._b.T_base_camera)
        in_front = (points @ T_b[:3, :3].T + T_b[:3, 3])[:, 2] > 0
        h = np.hstack([points, np.ones((len(points), 1))]) @ self.P_b.T
        ideal_b = h[:, :2] / h[:, 2:3]
        shown = self.shown("b", ideal_b)
        with np.errstate(invalid="ignore"):
            back = self.ideal("b", shown)
            unfolded = np.all(np.abs(back - ideal_b) < 1e-3, axis=1)
        width, height = size_b
        inside = (
            (shown[:, 0] >= 0)
            & (shown[:, 0] <= width)
            & (shown[:, 1] >= 0)
            & (shown[:, 1] <= height)
        )
        curve = shown[in_front & unfolded & inside]
        if len(curve) < 3:
            return curve
        kept = [0]
        for i in range(1, len(curve) - 1):
            if np.linalg.norm(curve[i] - curve[kept[-1]]) >= spacing_px:
                kept.append(i)
        return curve[[*kept, len(curve) - 1]]

    # -- triangulation ----------------------------------------------------------------------
    def triangulate(self, pixel_a: ArrayLike, pixel_b: ArrayLike) -> tuple[FloatArray, float]:
        """The 3-D point (m, base) of one matched pixel pair and the ray gap (m)."""
        result = triangulate_pixels(
            [self.P_a, self.P_b], [self.ideal("a", pixel_a), self.ideal("b", pixel_b)]
        )
        return np.asarray(result.point, dtype=float), float(np.atleast_1d(result.gap)[0])

    def triangulate_with_covariance(
        self, pixel_a: ArrayLike, pixel_b: ArrayLike, noise: StereoNoise
    ) -> tuple[FloatArray, FloatArray, float]:
        """Point (m, base), its 3 x 3 covariance (m²) and the ray gap (m) of a pixel pair."""
        uv_a = np.asarray(pixel_a, dtype=float).reshape(2)
        uv_b = np.asarray(pixel_b, dtype=float).reshape(2)
        point, gap = self.triangulate(uv_a, uv_b)
        # parameters: pixels a (2), pixels b (2), camera a (9), camera b (9)
        calib_sigma = [noise.rotation_rad] * 3 + [noise.translation_m] * 3
        calib_sigma += [noise.focal_rel, noise.principal_px, noise.principal_px]
        sigma = np.array([noise.pixel_px] * 4 + calib_sigma * 2)
        steps = np.array(
            [0.5] * 4
            + [1e-5] * 3
            + [1e-5] * 3
            + [1e-5, 0.5, 0.5]
            + [1e-5] * 3
            + [1e-5] * 3
            + [1e-5, 0.5, 0.5]
        )
        J = np.zeros((3, sigma.size))
        for i in range(sigma.size):
            if sigma[i] == 0.0:
                continue
            delta = np.zeros(sigma.size)
            delta[i] = steps[i]
            plus = self._triangulate_perturbed(uv_a, uv_b, delta)
            minus = self._triangulate_perturbed(uv_a, uv_b, -delta)
            J[:, i] = (plus - minus) / (2.0 * steps[i])
        covariance = (J * sigma**2) @ J.T
        return point, 0.5 * (covariance + covariance.T), gap

    def triangulate_constrained(
        self,
        pixels_a: ArrayLike,
        pixels_b: ArrayLike,
        noise: StereoNoise,
        spread_b: ArrayLike | None = None,
    ) -> _Vertices:
        """Vertices from clicked pixel pairs: each ``pixels_b[i]`` is moved onto the epipolar
        line of ``pixels_a[i]`` (:meth:`constrain_b`), then triangulated.

        Returns ``(points (n, 3) m, joint covariance (3n, 3n) m², gaps (n,) m)``: the covariance
        of all vertices from the clicks' noise (both coordinates of both images) and the two
        cameras' calibration errors, through the epipolar step. ``spread_b`` (n, 2, 2) px² is
        the covariance of where the operator believes each right-hand vertex is (None: the
        click noise ``noise.pixel_px`` in every direction); the handle is taken to the spot of
        its epipolar line that agrees best with that belief (:meth:`constrain_b`), so the
        spread along the line sets the vertex's depth error.
        """
        uv_a = np.asarray(pixels_a, dtype=float).reshape(-1, 2)
        uv_b = np.asarray(pixels_b, dtype=float).reshape(-1, 2)
        n = len(uv_a)
        click = noise.pixel_px**2 * np.eye(2)
        spread = np.broadcast_to(click if spread_b is None else spread_b, (n, 2, 2))
        spread = np.array(spread, dtype=float)
        key = (uv_a.tobytes(), uv_b.tobytes(), noise, spread.tobytes())
        if self._constrained is not None and self._constrained[0] == key:
            return _copied(self._constrained[1])
        calib_sigma = [noise.rotation_rad] * 3 + [noise.translation_m] * 3
        calib_sigma += [noise.focal_rel, noise.principal_px, noise.principal_px]
        sigma = np.array([noise.pixel_px] * (4 * n) + calib_sigma * 2)
        # the parameters' covariance: click noise on image a's pixels, each right-hand
        # vertex's spread on image b's, calibration errors
        C = np.diag(sigma**2)
        for i in range(n):
            block = slice(2 * n + 2 * i, 2 * n + 2 * i + 2)
            C[block, block] = spread[i]
        calib_steps = [1e-5] * 7 + [0.5, 0.5]
        steps = np.array([0.5] * (4 * n) + calib_steps * 2)
        metric = None if spread_b is None else spread
        points, gaps = self._constrained_points(uv_a, uv_b, np.zeros(sigma.size), metric)
        J = np.zeros((3 * n, sigma.size))
        for i in np.flatnonzero(np.diag(C)).tolist():
            delta = np.zeros(sigma.size)
            delta[i] = steps[i]
            plus, _ = self._constrained_points(uv_a, uv_b, delta, metric)
            minus, _ = self._constrained_points(uv_a, uv_b, -delta, metric)
            J[:, i] = (plus - minus).ravel() / (2.0 * steps[i])
        covariance = J @ C @ J.T
        result = (points, 0.5 * (covariance + covariance.T), gaps)
        self._constrained = (key, _copied(result))
        return result

    def _constrained_points(
        self, uv_a: FloatArray, uv_b: FloatArray, delta: FloatArray, spread: FloatArray | None
    ) -> tuple[FloatArray, FloatArray]:
        n = len(uv_a)
        pair = self
        if np.any(delta[4 * n :]):
            cam_a = self._a.perturbed(delta[4 * n : 4 * n + 9])
            cam_b = self._b.perturbed(delta[4 * n + 9 :])
            pair = StereoPair(
                cam_a.K, cam_a.T_base_camera, cam_b.K, cam_b.T_base_camera, cam_a.dist, cam_b.dist
            )
        a = uv_a + delta[: 2 * n].reshape(n, 2)
        b = pair.constrain_b(a, uv_b + delta[2 * n : 4 * n].reshape(n, 2), spread).reshape(n, 2)
        result = triangulate_pixels([pair.P_a, pair.P_b], [pair.ideal("a", a), pair.ideal("b", b)])
        return np.asarray(result.point, dtype=float).reshape(n, 3), np.atleast_1d(result.gap)

    def _triangulate_perturbed(
        self, uv_a: FloatArray, uv_b: FloatArray, delta: FloatArray
    ) -> FloatArray:
        cam_a = self._a.perturbed(delta[4:13])
        cam_b = self._b.perturbed(delta[13:22])
        result = triangulate_pixels(
            [cam_a.matrix(), cam_b.matrix()],
            [self.ideal("a", uv_a) + delta[0:2], self.ideal("b", uv_b) + delta[2:4]],
        )
        return np.asarray(result.point, dtype=float)

    def _cam(self, side: str) -> _Camera:
        if side == "a":
            return self._a
        if side == "b":
            return self._b
        raise ValueError(f"camera side must be 'a' or 'b', got {side!r}")


def _f(values: ArrayLike, shape: tuple[int, ...]) -> FloatArray:
    array = np.asarray(values, dtype=float)
    if array.shape != shape or not np.all(np.isfinite(array)):
        raise ValueError(f"expected finite numbers of shape {shape}, got {array.shape}: {array}")
    return array


def _copied(vertices: _Vertices) -> _Vertices:
    """Copies of the three arrays (the cache's own are never handed out)."""
    points, covariance, gaps = vertices
    return np.copy(points), np.copy(covariance), np.copy(gaps)
