"""The camera-pose tool's solver (report section 5.5): an unknown mount from clicked points.

A camera sits at the end of a chain of transforms from the world. One link of that chain, the
*mount* ``T_parent_child``, is unknown (or known badly: the camera was bolted on a few degrees and
centimetres off); everything else is known for every snapshot::

    T_world_camera(i) = T_world_parent(i) . T_parent_child . T_child_camera(i)

* camera on a PTU head: parent = PTU head (``T_world_parent`` = the PTU's base pose times its
  pan/tilt kinematics at the snapshot), child = the camera, ``T_child_camera`` = identity;
* wrist camera: parent = tool (the arm's forward kinematics at the snapshot), child = camera;
* PTU base in the world: parent = world (identity), child = PTU base, ``T_child_camera`` = the
  pan/tilt kinematics times the camera's mount: the rays of different snapshots do not meet, the
  report's non-perspective n-point case.

The operator clicks calibration points in the images (pixels) and picks the same points in the
3-D model (world coordinates, metres). With three or more pairs over one or several snapshots
the mount is solved by :func:`umbra.modules.calib.npnp.solve_npnp`: its input frame is the parent
(``x = T_parent_world(i) X``), its unknown ``(R, d)`` is ``T_child_parent``, and each view's
camera extrinsics are ``T_camera_child(i)``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from umbra.modules.calib.camera_model import PinholeCamera
from umbra.modules.calib.errors import DegenerateGeometryError
from umbra.modules.calib.npnp import View, solve_npnp
from umbra.modules.calib.rotations import invert_transform, skew, vector_from_rotation
from umbra.modules.geometry.transforms import transform_points

FloatArray = NDArray[np.float64]


def _as_transform(value: ArrayLike, what: str) -> FloatArray:
    T = np.asarray(value, dtype=float)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise DegenerateGeometryError(f"{what} must be a finite 4x4 transform, got shape {T.shape}")
    return T


@dataclass(frozen=True, eq=False)
class MountSnapshot:
    """One snapshot: the camera (intrinsics and distortion; its extrinsics are ignored), the
    known chain on both sides of the mount when it was taken, and clicked pairs.

    ``points_world`` ``(n, 3)`` metres in the world; ``pixels`` ``(n, 2)`` as measured (distorted).
    """

    camera: PinholeCamera
    points_world: FloatArray
    pixels: FloatArray
    T_world_parent: FloatArray = field(default_factory=lambda: np.eye(4))
    T_child_camera: FloatArray = field(default_factory=lambda: np.eye(4))

    def __post_init__(self) -> None:
        points = np.asarray(self.points_world, dtype=float).reshape(-1, 3)
        pixels = np.asarray(self.pixels, dtype=float).reshape(-1, 2)
        if len(points) != len(pixels):
            raise DegenerateGeometryError(
                f"snapshot has {len(points)} 3-D points but {len(pixels)} pixels"
            )
        if not (np.all(np.isfinite(points)) and np.all(np.isfinite(pixels))):
            raise DegenerateGeometryError("snapshot points and pixels must be finite")
        object.__setattr__(self, "points_world", points)
        object.__setattr__(self, "pixels", pixels)
        object.__setattr__(
            self, "T_world_parent", _as_transform(self.T_world_parent, "T_world_parent")
        )
        object.__setattr__(
            self, "T_child_camera", _as_transform(self.T_child_camera, "T_child_camera")
        )

    def T_world_camera(self, T_parent_child: ArrayLike) -> FloatArray:
        """The camera's pose in the world for a given mount (4x4)."""
        return self.T_world_parent @ np.asarray(T_parent_child, dtype=float) @ self.T_child_camera

    def posed_camera(self, T_parent_child: ArrayLike) -> PinholeCamera:
        """The camera with extrinsics ``T_camera_world`` for a given mount."""
        return self.camera.with_extrinsic_matrix(
            invert_transform(self.T_world_camera(T_parent_child))
        )

    def reprojection(self, T_parent_child: ArrayLike) -> FloatArray:
        """Predicted minus measured pixels ``(n, 2)`` for a given mount."""
        return self.posed_camera(T_parent_child).project(self.points_world) - self.pixels


@dataclass(frozen=True, eq=False)
class MountResult:
    """The solved mount ``T_parent_child`` (4x4, metres) and every point's residual (pixels,
    predicted minus measured, per snapshot), before (at the initial mount, if given) and after."""

    T_parent_child: FloatArray
    residuals: list[FloatArray]
    rms_px: float
    iterations: int
    initial_residuals: list[FloatArray] | None = None
    #: the start the solution came from, and what the caller must know (see ``solve_npnp``)
    start: str = ""
    warnings: tuple[str, ...] = ()
    #: 6x6 covariance of the mount at the solution: a rotation vector [rad] applied on the left
    #: of the solved rotation (``R <- exp([φ]_x) R``, parent frame), then the translation [m]
    #: (parent frame); the clicks' noise as given, else estimated from the residuals
    covariance: FloatArray | None = None
    #: degrees of freedom of the noise behind the covariance: clicks' coordinates less 6 when
    #: estimated from the residuals, infinite when given
    noise_dof: float = float("inf")

    @property
    def standard_errors(self) -> dict[str, float]:
        """One-sigma errors of the mount: ``rx ry rz`` [rad] about the parent's axes, ``x y z``
        [m] (empty without a covariance)."""
        if self.covariance is None:
            return {}
        sigma = np.sqrt(np.abs(np.diag(self.covariance)))
        return dict(zip(("rx", "ry", "rz", "x", "y", "z"), sigma.tolist(), strict=True))

    def interval_95(self) -> dict[str, float]:
        """Half-widths of the 95 % intervals of the mount's parameters (``rx ry rz`` [rad],
        ``x y z`` [m]): Student's t quantile at ``noise_dof`` times the standard errors (1.96
        when the noise was given)."""
        from scipy.stats import t as student

        factor = float(student.ppf(0.975, self.noise_dof))
        return {name: factor * se for name, se in self.standard_errors.items()}

    @property
    def max_px(self) -> float:
        return max(
            (float(np.max(np.linalg.norm(r, axis=1))) for r in self.residuals if len(r)),
            default=0.0,
        )


def mount_views(snapshots: Sequence[MountSnapshot]) -> list[View]:
    """The nPnP views of the mount problem (input frame: parent; output frame: child)."""
    views = []
    for s in snapshots:
        points_parent = transform_points(invert_transform(s.T_world_parent), s.points_world)
        camera = s.camera.with_extrinsic_matrix(invert_transform(s.T_child_camera))
        views.append(View(camera, points_parent, s.pixels))
    return views


def solve_mount(
    snapshots: Sequence[MountSnapshot],
    initial_T_parent_child: ArrayLike | None = None,
    pixel_sigma: float | None = None,
) -> MountResult:
    """Solve the mount from clicked pairs over one or several snapshots.

    Args:
        snapshots: at least three point/pixel pairs in all.
        initial_T_parent_child: the believed (nominal) mount, one of the starts (the solver
            also starts from PnP on every snapshot and the linear generalized-camera pose, and
            keeps the lowest cost; ``warnings`` says when the given start led elsewhere).
        pixel_sigma: the clicks' noise (px per coordinate): residuals beyond it are reported.

    Raises:
        DegenerateGeometryError, NotConvergedError (both ``CalibrationError``).
    """
    views = mount_views(snapshots)
    initial = None
    initial_residuals = None
    if initial_T_parent_child is not None:
        T0 = _as_transform(initial_T_parent_child, "initial mount")
        initial = invert_transform(T0)
        with np.errstate(divide="ignore", invalid="ignore"):  # a point at depth 0: NaN
            initial_residuals = [s.reprojection(T0) for s in snapshots]
    result = solve_npnp(views, initial, pixel_sigma=pixel_sigma)
    T_parent_child = invert_transform(result.T)
    residuals = [s.reprojection(T_parent_child) for s in snapshots]
    all_r = np.vstack([r for r in residuals if len(r)])
    rms = float(np.sqrt(np.mean(np.sum(all_r**2, axis=1))))
    return MountResult(
        T_parent_child,
        residuals,
        rms,
        result.iterations,
        initial_residuals,
        result.start,
        result.warnings,
        _mount_covariance(result.R, result.d, result.covariance),
        float("inf") if pixel_sigma is not None else float(max(all_r.size - 6, 1)),
    )


def _mount_covariance(
    R: FloatArray, d: FloatArray, covariance: FloatArray | None
) -> FloatArray | None:
    """The covariance of the mount ``(Rᵀ, -Rᵀ d)`` from that of the solved ``T_child_parent =
    (R, d)`` (``dθ`` on the left of ``R``, then ``d``): first order, a left rotation ``dθ`` of
    ``R`` is ``-Rᵀ dθ`` on the left of ``Rᵀ``, and the mount's translation moves by
    ``-Rᵀ (dd + [d]_x dθ)``."""
    if covariance is None:
        return None
    jacobian = np.zeros((6, 6))
    jacobian[:3, :3] = -R.T
    jacobian[3:, :3] = -R.T @ skew(d)
    jacobian[3:, 3:] = -R.T
    return jacobian @ covariance @ jacobian.T


def pose_error(T_estimate: ArrayLike, T_truth: ArrayLike) -> tuple[float, float]:
    """``(rotation error in radians, translation error in metres)`` between two 4x4 poses."""
    A = np.asarray(T_estimate, dtype=float)
    B = np.asarray(T_truth, dtype=float)
    angle = float(np.linalg.norm(vector_from_rotation(A[:3, :3].T @ B[:3, :3])))
    return angle, float(np.linalg.norm(A[:3, 3] - B[:3, 3]))
