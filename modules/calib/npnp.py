"""Appendix C of the Sandia report: the non-perspective n-point pose problem (nPnP).

Unknown: a rigid transform ``T = (R, d)`` taking points from an *input* frame to an *output*
frame (``y = R x + d``). Known: one or more views; view ``i`` is a calibrated camera whose
extrinsics ``(R_i, d_i)`` take output-frame points into that camera's frame, with pixels measured
for points given in the input frame. The rays of different views do not meet at one point, so
this is not the PnP problem of a single perspective camera.

Gauss-Newton (as in Appendix C): linearize the pose about the current estimate with a
small-angle update ``R <- exp([dtheta]_x) R``, ``d <- d + dd`` (first order ``(I + [dtheta]_x) R``,
equation 37), solve the stacked linear equations of all views for ``(dtheta, dd)`` by least
squares, and rebuild ``R`` exactly from the axis-angle ``dtheta`` (equations 49-51). The residual
is the ideal-pixel reprojection error; measured pixels are undistorted first. A step that raises
the cost is halved (backtracking), which keeps the iteration from diverging on a poor start.

Initial guess, if none is given: ``cv2.solvePnP`` (SQPnP) on the view with the most points
(at least four), moved into the output frame; otherwise a linear generalized-camera solution
(``[w]_x (R x + d - o) = 0`` for each ray ``o + s w``, at least six points on rays from more
than one centre), projected onto the rotations.

Several starts, one answer: Gauss-Newton finds the minimum nearest its start, and a pose problem
has others (a PnP case a few degrees from the truth and one 100 degrees away can both be
minima; a planar target seen from afar has two, mirror images of each other about the line of
sight). :func:`solve_npnp` runs from the given start and from global ones (on every view with
four points or more, SQPnP, or OpenCV's iterative PnP where SQPnP fails, and beside it EPnP on a
view whose points are off one plane, both of IPPE's poses on one whose points are coplanar, one
for each of the two planar minima; the linear generalized-camera solution, which needs points
off one plane) and keeps the lowest cost. The given start runs first, the others from the
lowest reprojection cost up, so the first runs most often reach the best minimum. The cost of
the extra starts is paid only where they lead somewhere new: a start within ``SAME_BASIN_DEG``
of a minimum already found or of a start already run would end there and is not run, a run
other than the caller's stops as soon as an iterate comes that near a minimum already found,
and a start other than the caller's that puts a point behind a camera is not run.
``PoseResult.warnings`` says when the given start led elsewhere (a bad start), when another
minimum fits the clicks about as well (geometry that does not decide), and, given the click
noise ``pixel_sigma``, when even the best residual is more than the noise explains (a
chi-square test at 99.9 %).

``PoseResult.covariance`` is the Gauss-Newton covariance ``s² (JᵀJ)⁻¹`` at the solution, in the
solver's own parameters: a rotation vector ``dθ`` [rad] applied on the left of the fitted ``R``
(``R <- exp([dθ]_x) R``, output frame) and the translation ``d`` [m], ``s`` the click noise
(``pixel_sigma`` when given, else estimated from the residuals).
"""

from __future__ import annotations

import contextlib
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from umbra.modules.calib.camera_model import PinholeCamera
from umbra.modules.calib.errors import DegenerateGeometryError, NotConvergedError
from umbra.modules.calib.npnp_warnings import GIVEN, MIN_PIXEL_SIGMA, pose_warnings
from umbra.modules.calib.rotations import nearest_rotation, rotation_from_vector, transform

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class View:
    """Pixels of input-frame points seen by a camera whose extrinsics are relative to the output
    frame (``camera.R``, ``camera.d`` take output-frame points, metres, into the camera frame)."""

    camera: PinholeCamera
    points: FloatArray
    pixels: FloatArray

    def __post_init__(self) -> None:
        points = np.asarray(self.points, dtype=float).reshape(-1, 3)
        pixels = np.asarray(self.pixels, dtype=float).reshape(-1, 2)
        if len(points) != len(pixels):
            raise DegenerateGeometryError(f"view has {len(points)} points but {len(pixels)} pixels")
        object.__setattr__(self, "points", points)
        object.__setattr__(self, "pixels", pixels)


@dataclass(frozen=True, eq=False)
class PoseResult:
    """The solved transform (``y = R x + d``; metres), residual pixels per view, their RMS."""

    R: FloatArray
    d: FloatArray
    rms_px: float
    residuals: list[FloatArray]
    iterations: int
    #: which start the solution came from, and what went wrong on the way (empty: nothing)
    start: str = ""
    warnings: tuple[str, ...] = ()
    #: 6x6 covariance of (dθ [rad] about the fitted R, output frame; d [m]); see the module doc
    covariance: FloatArray | None = None

    @property
    def T(self) -> FloatArray:
        """4x4 homogeneous form of ``(R, d)``."""
        return transform(self.R, self.d)


@dataclass(frozen=True, eq=False)
class _Prepared:
    K2: FloatArray  # 2x2 upper-left block of K
    principal: FloatArray
    A_R: FloatArray
    A_t: FloatArray
    points: FloatArray
    ideal: FloatArray


def _prepare(views: Sequence[View]) -> list[_Prepared]:
    prepared = []
    for view in views:
        if len(view.points) == 0:
            continue
        K = view.camera.K
        ideal = view.camera.ideal_pixels(view.pixels)
        if not np.all(np.isfinite(ideal)):
            raise DegenerateGeometryError("a pixel cannot be undistorted (outside the lens model)")
        prepared.append(
            _Prepared(K[:2, :2], K[:2, 2], view.camera.R, view.camera.d, view.points, ideal)
        )
    total = sum(len(p.points) for p in prepared)
    if total < 3:
        raise DegenerateGeometryError(f"a pose needs at least 3 point/pixel pairs, got {total}")
    return prepared


@dataclass(frozen=True, eq=False)
class _Stacked:
    """Every view's points in one set of arrays (one row per point), so that the residuals and
    their Jacobian take a few array operations whatever the number of views: each point carries
    its view's extrinsics ``A_R, A_t`` (output frame -> camera) and ``K2, principal`` [px]."""

    points: FloatArray  # (n, 3) input frame [m]
    A_R: FloatArray  # (n, 3, 3)
    A_t: FloatArray  # (n, 3) [m]
    K2: FloatArray  # (n, 2, 2) [px]
    principal: FloatArray  # (n, 2) [px]
    ideal: FloatArray  # (n, 2) undistorted measured pixels [px]
    centre: FloatArray  # (3,) the points' mean, input frame [m]


def _stack(prepared: list[_Prepared] | _Stacked) -> _Stacked:
    """The views of ``prepared`` in one :class:`_Stacked` (returned as is when it is one)."""
    if isinstance(prepared, _Stacked):
        return prepared
    counts = [len(p.points) for p in prepared]

    def each(name: str) -> FloatArray:
        return np.concatenate(
            [
                np.broadcast_to(getattr(p, name), (k, *np.shape(getattr(p, name))))
                for p, k in zip(prepared, counts, strict=True)
            ]
        )

    points = np.vstack([p.points for p in prepared])
    return _Stacked(
        points,
        each("A_R"),
        each("A_t"),
        each("K2"),
        each("principal"),
        np.vstack([p.ideal for p in prepared]),
        points.mean(axis=0),
    )


def _residuals_and_jacobian(
    stacked: _Stacked, R: FloatArray, d: FloatArray, with_jacobian: bool = True
) -> tuple[FloatArray, FloatArray | None, float]:
    """Residuals (px, flat, point by point in view order), their Jacobian in ``(dtheta, dd)``
    and the least depth [m]; a point at depth 0 gives non-finite values (no warning: the
    callers test for them)."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        return _residuals_and_jacobian_raw(stacked, R, d, with_jacobian)


def _residuals_and_jacobian_raw(
    s: _Stacked, R: FloatArray, d: FloatArray, with_jacobian: bool
) -> tuple[FloatArray, FloatArray | None, float]:
    rotated = s.points @ R.T  # R x, output frame
    c = np.matmul(s.A_R, (rotated + d)[:, :, None])[:, :, 0] + s.A_t  # camera frame
    inv_z = 1.0 / c[:, 2]
    normalized = c[:, :2] * inv_z[:, None]
    predicted = np.matmul(s.K2, normalized[:, :, None])[:, :, 0] + s.principal
    r = (predicted - s.ideal).ravel()
    min_depth = float(c[:, 2].min())
    if not with_jacobian:
        return r, None, min_depth
    # d pixel / d camera point: K2 [[1/z, 0, -x/z^2], [0, 1/z, -y/z^2]]
    B = np.zeros((len(c), 2, 3))
    B[:, 0, 0] = inv_z
    B[:, 1, 1] = inv_z
    B[:, :, 2] = -normalized * inv_z[:, None]
    M = np.matmul(np.matmul(s.K2, B), s.A_R)  # d pixel / d output-frame point (= d / dd)
    # d pixel / d theta = -M [R x]_x: each row m of M becomes (R x) x m
    v0, v1, v2 = (rotated[:, None, k] for k in range(3))
    m0, m1, m2 = M[:, :, 0], M[:, :, 1], M[:, :, 2]
    J = np.empty((len(c), 2, 6))
    J[:, :, 0] = v1 * m2 - v2 * m1
    J[:, :, 1] = v2 * m0 - v0 * m2
    J[:, :, 2] = v0 * m1 - v1 * m0
    J[:, :, 3:] = M
    return r, J.reshape(-1, 6), min_depth


def initial_pose(views: Sequence[View]) -> tuple[FloatArray, FloatArray]:
    """Starting pose for :func:`solve_npnp` (see module docstring)."""
    return _initial_pose(_prepare(views))


def _check_spread(prepared: list[_Prepared]) -> None:
    """DegenerateGeometryError when the points (all views, input frame) coincide or lie on one
    line (within 1e-4 of their extent): rotation about that line is then undetermined, and
    SQPnP asserts on such input."""
    points = np.vstack([p.points for p in prepared])
    centred = points - points.mean(axis=0)
    spread = np.linalg.svd(centred, compute_uv=False)
    if spread[0] <= 1e-9:
        raise DegenerateGeometryError(
            f"all {len(points)} points are at one place; the pose needs >= 3 points not on one line"
        )
    if spread[1] <= 1e-4 * spread[0]:
        raise DegenerateGeometryError(
            f"the {len(points)} points lie on one line (spread {spread[1]:.3g} across it vs "
            f"{spread[0]:.3g} along it); the pose needs >= 3 points not on one line"
        )


def _initial_pose(prepared: list[_Prepared]) -> tuple[FloatArray, FloatArray]:
    _check_spread(prepared)
    best = max(prepared, key=lambda p: len(p.points))
    if len(best.points) >= 4:
        return _single_view_pose(best)
    return _linear_generalized_pose(prepared)


def _single_view_pose(p: _Prepared, flag: int | None = None) -> tuple[FloatArray, FloatArray]:
    """Pose of the best view by OpenCV's PnP with ``flag`` (None: ``cv2.SOLVEPNP_SQPNP``)."""
    import cv2

    normalized = np.linalg.solve(p.K2, (p.ideal - p.principal).T).T
    try:
        ok, rvec, tvec = cv2.solvePnP(
            p.points.astype(np.float64),
            normalized.astype(np.float64),
            np.eye(3),
            None,
            flags=cv2.SOLVEPNP_SQPNP if flag is None else flag,
        )
    except cv2.error as error:  # SQPnP asserts on degenerate input
        message = str(error).strip().splitlines()[-1].rpartition("error: ")[2]
        raise DegenerateGeometryError(f"single-view PnP refused the points: {message}") from None
    if not ok:
        raise DegenerateGeometryError("single-view PnP found no pose for the initial guess")
    R_cam_in = rotation_from_vector(rvec.ravel())
    # camera <- output (A) <- input (T):  T = A^-1 T_cam_in
    R = p.A_R.T @ R_cam_in
    d = p.A_R.T @ (tvec.ravel() - p.A_t)
    return R, d


def _coplanar(points: FloatArray) -> bool:
    """True when the points lie on one plane (across it within 1e-3 of their extent)."""
    spread = np.linalg.svd(points - points.mean(axis=0), compute_uv=False)
    return bool(spread[-1] <= 1e-3 * spread[0])


def _planar_poses(p: _Prepared) -> list[tuple[FloatArray, FloatArray]]:
    """Both poses IPPE finds for a view of coplanar points (the two minima of a planar target
    seen from afar, mirror images about the line of sight), in the output frame. IPPE wants the
    plane at z = 0: the points are moved there and the poses moved back."""
    import cv2

    centre = p.points.mean(axis=0)
    _, _, Vt = np.linalg.svd(p.points - centre)
    B = Vt if np.linalg.det(Vt) > 0 else Vt * np.array([[1.0], [1.0], [-1.0]])
    on_plane = (p.points - centre) @ B.T
    on_plane[:, 2] = 0.0
    normalized = np.linalg.solve(p.K2, (p.ideal - p.principal).T).T
    _, rvecs, tvecs, _ = cv2.solvePnPGeneric(
        on_plane, normalized, np.eye(3), None, flags=cv2.SOLVEPNP_IPPE
    )
    poses = []
    for rvec, tvec in zip(rvecs, tvecs, strict=True):
        R_cam_plane = rotation_from_vector(np.asarray(rvec).ravel())
        # camera <- plane <- input:  x_plane = B (x - centre)
        R_cam_in = R_cam_plane @ B
        t_cam_in = np.asarray(tvec).ravel() - R_cam_in @ centre
        poses.append((p.A_R.T @ R_cam_in, p.A_R.T @ (t_cam_in - p.A_t)))
    return poses


def linear_generalized_pose(views: Sequence[View]) -> tuple[FloatArray, FloatArray]:
    """Linear pose from rays of several centres: ``[w]_x (R x + d - o) = 0`` per ray.

    Needs at least six points not all on one plane, seen from more than one camera centre.
    """
    return _linear_generalized_pose(_prepare(views))


def _linear_generalized_pose(prepared: list[_Prepared]) -> tuple[FloatArray, FloatArray]:
    # one ray o + s w per point: [w]_x (R x + d) = [w]_x o, 3 rows in (vec(R) row-major, d)
    origins, directions = [], []
    for p in prepared:
        normalized = np.linalg.solve(p.K2, (p.ideal - p.principal).T).T
        rays = np.hstack([normalized, np.ones((len(normalized), 1))]) @ p.A_R
        directions.append(rays / np.linalg.norm(rays, axis=1, keepdims=True))
        origins.append(np.broadcast_to(-p.A_R.T @ p.A_t, rays.shape))
    W = _skews(np.vstack(directions))  # (n, 3, 3)
    X = np.vstack([p.points for p in prepared])
    rotation_part = (W[:, :, :, None] * X[:, None, None, :]).reshape(-1, 3, 9)  # W kron(I, x)
    A = np.concatenate([rotation_part, W], axis=2).reshape(-1, 12)
    b = np.matmul(W, np.vstack(origins)[:, :, None]).ravel()
    singular = np.linalg.svd(A, compute_uv=False)
    if len(singular) < 12 or singular[11] <= 1e-9 * singular[0]:
        raise DegenerateGeometryError(
            "cannot find an initial pose: no view has 4 points and the rays do not determine a "
            "linear solution (need >= 6 non-coplanar points from more than one camera centre); "
            "give an initial pose"
        )
    solution = np.linalg.lstsq(A, b, rcond=None)[0]
    R = nearest_rotation(solution[:9].reshape(3, 3))
    d = np.linalg.lstsq(A[:, 9:], b - A[:, :9] @ R.ravel(), rcond=None)[0]
    return R, d


def _skews(vectors: FloatArray) -> FloatArray:
    """``[v]_x`` for each row of ``vectors`` ``(n, 3)`` -> ``(n, 3, 3)``."""
    out = np.zeros((len(vectors), 3, 3))
    x, y, z = vectors[:, 0], vectors[:, 1], vectors[:, 2]
    out[:, 0, 1], out[:, 0, 2], out[:, 1, 2] = -z, y, -x
    out[:, 1, 0], out[:, 2, 0], out[:, 2, 1] = z, -y, x
    return out


class _SameMinimum(Exception):
    """Raised by :func:`_gauss_newton` when its iterate enters the basin of a minimum already
    found (within ``SAME_BASIN_DEG`` of it, see :func:`_near`): the run would end there."""


def _gauss_newton(
    prepared: list[_Prepared] | _Stacked,
    R: FloatArray,
    d: FloatArray,
    max_iterations: int,
    step_tolerance: float,
    known: Sequence[tuple[FloatArray, FloatArray]] = (),
) -> tuple[FloatArray, FloatArray, FloatArray, int]:
    """Gauss-Newton from ``(R, d)``: the minimum's ``R, d``, residuals and iteration count.

    Raises _SameMinimum as soon as an iterate comes within the basin of one of the ``known``
    minima ``(R, d)`` (the remaining iterations would only refine a minimum already found)."""
    stacked = _stack(prepared)
    R = nearest_rotation(R)
    r, J, min_depth = _residuals_and_jacobian(stacked, R, d)
    assert J is not None
    if not (np.all(np.isfinite(r)) and np.all(np.isfinite(J))):
        raise NotConvergedError(
            "the reprojection is not finite at this start (a point at a camera's centre, at "
            "depth 0, or a focal length too small to divide by)"
        )
    cost = float(r @ r)
    iterations = 0
    for iterations in range(1, max_iterations + 1):  # noqa: B007
        step = _gauss_newton_step(J, r)
        if np.max(np.abs(step)) < step_tolerance:
            break
        predicted = J @ step
        if -(2.0 * float(r @ predicted) + float(predicted @ predicted)) <= 1e-12 * cost:
            break  # the step would lower the cost by less than 1e-12 of itself: at the minimum
        scale = 1.0
        for _ in range(20):
            # The full step is taken nearly always: its Jacobian is computed with its residuals.
            R_new = rotation_from_vector(scale * step[:3]) @ R
            d_new = d + scale * step[3:]
            r_new, J_new, depth_new = _residuals_and_jacobian(
                stacked, R_new, d_new, with_jacobian=scale == 1.0
            )
            cost_new = float(r_new @ r_new)
            if cost_new <= cost * (1.0 + 1e-12) or not np.isfinite(cost):
                break
            scale *= 0.5
        else:
            break  # no descent along the Gauss-Newton step: at a minimum to machine precision
        R, d, min_depth = R_new, d_new, depth_new
        if known and min_depth > 0 and _near(R, d, known, stacked.centre):
            raise _SameMinimum
        if J_new is None:
            r, J, _ = _residuals_and_jacobian(stacked, R, d)
            assert J is not None  # asked for (with_jacobian defaults to True)
        else:
            r, J = r_new, J_new
        previous, cost = cost, float(r @ r)
        if np.max(np.abs(scale * step)) < step_tolerance or previous - cost <= 1e-14 * previous:
            break
    else:
        raise NotConvergedError(f"nPnP did not converge in {max_iterations} iterations")
    if not min_depth > 0:
        raise NotConvergedError("nPnP converged to a pose with points behind a camera")
    return R, d, r, iterations


def _gauss_newton_step(J: FloatArray, r: FloatArray) -> FloatArray:
    """The least-squares step ``J step = -r`` (6 unknowns), by the normal equations with the
    columns scaled to unit length; DegenerateGeometryError when J does not have full rank."""
    scale = np.sqrt(np.einsum("ij,ij->j", J, J))
    if not np.all(scale > 0.0):
        raise DegenerateGeometryError(_UNDETERMINED)
    Js = J / scale
    eigen, vectors = np.linalg.eigh(Js.T @ Js)
    if eigen[0] <= 1e-20 * eigen[-1]:  # singular values' ratio 1e-10
        raise DegenerateGeometryError(_UNDETERMINED)
    return (vectors @ ((vectors.T @ -(Js.T @ r)) / eigen)) / scale


_UNDETERMINED = (
    "the observations do not determine all six pose parameters "
    "(need >= 3 points not on one line, seen with enough parallax)"
)
#: A start within this angle [deg] of a minimum already found, or of a start already run, ends
#: where that one did: it is not run, and a run whose iterate comes this near a minimum already
#: found stops there. (The minima a pose problem has besides the best lie tens of degrees
#: away: a planar target's mirror pose is twice its tilt from facing the camera.)
SAME_BASIN_DEG = 3.0


def _near(
    R0: FloatArray,
    d0: FloatArray,
    poses: Sequence[tuple[FloatArray, FloatArray]],
    centre: FloatArray,
) -> bool:
    """True when the start ``(R0, d0)`` lies within ``SAME_BASIN_DEG`` of one of ``poses`` and
    puts the points' ``centre`` (input frame, m) within 5 % of its distance of where that one
    does."""
    for R, d in poses:
        cos = 0.5 * (float(np.vdot(R, R0)) - 1.0)  # trace(R^T R0) = sum of R * R0
        if cos > _SAME_BASIN_COS:
            here = R @ centre + d
            gap = R0 @ centre + d0 - here
            if float(gap @ gap) <= 0.0025 * float(here @ here):  # within 5 % of the distance
                return True
    return False


#: Gauss-Newton iterations of a start other than the caller's: one that has not converged by
#: then is far from any minimum the others do not reach (converging runs take under 20).
EXTRA_START_ITERATIONS = 40


_SAME_BASIN_COS = float(np.cos(np.deg2rad(SAME_BASIN_DEG)))


def solve_npnp(
    views: Sequence[View],
    initial: ArrayLike | tuple[ArrayLike, ArrayLike] | None = None,
    max_iterations: int = 100,
    step_tolerance: float = 1e-12,
    pixel_sigma: float | None = None,
) -> PoseResult:
    """Solve the non-perspective n-point problem: Gauss-Newton from several starts.

    Args:
        views: one or more :class:`View`; at least three pairs in all.
        initial: a starting pose, a 4x4 transform or ``(R, d)``, tried with the global starts.
        max_iterations: Gauss-Newton iterations before giving up, per start.
        step_tolerance: stop when the update is smaller than this (radians and metres).
        pixel_sigma: the clicks' noise (px per coordinate), for the residual check; None: it is
            estimated from the best residual. Either is floored at 0.01 px
            (``npnp_warnings.MIN_PIXEL_SIGMA``), so noise-free clicks give a finite test.

    Raises:
        DegenerateGeometryError: too few pairs or a configuration that does not fix the pose
            (the Jacobian at the best minimum, not at a start, is rank-deficient).
        NotConvergedError: no start converged to a pose with the points in front of the cameras.
    """
    prepared = _prepare(views)
    _check_spread(prepared)
    stacked = _stack(prepared)
    found: list[tuple[str, FloatArray, FloatArray, FloatArray, int]] = []
    failed: dict[str, str] = {}
    tried: list[tuple[FloatArray, FloatArray]] = []
    for name, R0, d0 in _ranked(stacked, _starts(prepared, initial), failed):
        if _near(R0, d0, tried, stacked.centre):
            continue
        tried.append((R0, d0))
        given = name == GIVEN
        budget = max_iterations if given else min(max_iterations, EXTRA_START_ITERATIONS)
        known = [] if given else [(f[1], f[2]) for f in found]
        try:
            found.append((name, *_gauss_newton(stacked, R0, d0, budget, step_tolerance, known)))
            tried.append((found[-1][1], found[-1][2]))
        except _SameMinimum:
            continue
        except (DegenerateGeometryError, NotConvergedError) as error:
            failed[name] = str(error)
        except np.linalg.LinAlgError as error:  # the linear algebra of this start broke down
            failed[name] = f"numerical failure ({error})"
    if not found:
        reasons = "; ".join(f"{name}: {why}" for name, why in failed.items())
        if all("determine" in why for why in failed.values()):
            raise DegenerateGeometryError(reasons)
        raise NotConvergedError(f"no start reached a pose with every point in front ({reasons})")
    found.sort(key=lambda f: float(f[3] @ f[3]))
    name, R, d, r, iterations = found[0]
    _, J, _ = _residuals_and_jacobian(stacked, R, d)
    assert J is not None
    singular = np.linalg.svd(J, compute_uv=False)
    if singular[-1] <= 1e-9 * singular[0]:
        raise DegenerateGeometryError(
            "the observations do not determine all six pose parameters at the best pose found "
            "(need >= 3 points not on one line, seen with enough parallax)"
        )
    warnings = pose_warnings(found, failed, initial is not None, pixel_sigma)
    blocks = np.split(r.reshape(-1, 2), np.cumsum([len(p.points) for p in prepared])[:-1])
    rms_px = float(np.sqrt(np.mean(np.sum(r.reshape(-1, 2) ** 2, axis=1))))
    covariance = _covariance(J, r, pixel_sigma)
    return PoseResult(R, d, rms_px, blocks, iterations, name, warnings, covariance)


def _ranked(
    stacked: _Stacked, starts: list[tuple[str, FloatArray, FloatArray]], failed: dict[str, str]
) -> list[tuple[str, FloatArray, FloatArray]]:
    """The caller's start first, then the others from the lowest reprojection cost up (the
    first run then most often reaches the best minimum, and later runs stop on entering its
    basin); a start other than the caller's that puts a point at or behind a camera's centre
    plane is left out and named in ``failed`` (Gauss-Newton, which only lowers the cost, cannot
    cross the infinite residual at depth 0 to the side the points are seen from). The starts
    other than the caller's are rotations already (from rotation vectors, or projected)."""
    given: list[tuple[str, FloatArray, FloatArray]] = []
    others: list[tuple[float, int, tuple[str, FloatArray, FloatArray]]] = []
    for name, R0, d0 in starts:
        if name == GIVEN:
            given.append((name, R0, d0))
            continue
        r, _, min_depth = _residuals_and_jacobian(stacked, R0, d0, False)
        if min_depth <= 0.0:  # (a NaN depth is left to Gauss-Newton, which names it)
            failed[name] = "it puts a point behind a camera"
            continue
        cost = float(r @ r)
        others.append((cost if np.isfinite(cost) else np.inf, len(others), (name, R0, d0)))
    return given + [start for _, _, start in sorted(others, key=lambda o: o[:2])]


def _covariance(J: FloatArray, r: FloatArray, pixel_sigma: float | None) -> FloatArray:
    """``s² (JᵀJ)⁻¹`` at the solution: ``s`` the given click noise, else the residuals' own
    (``r·r / (m - 6)``, ``m`` the pixel coordinates; the floor ``MIN_PIXEL_SIGMA`` either way)."""
    estimated = float(r @ r) / max(r.size - 6, 1)
    variance = max(estimated if pixel_sigma is None else pixel_sigma**2, MIN_PIXEL_SIGMA**2)
    return variance * np.linalg.inv(J.T @ J)


def _starts(
    prepared: list[_Prepared], initial: ArrayLike | tuple[ArrayLike, ArrayLike] | None
) -> list[tuple[str, FloatArray, FloatArray]]:
    import cv2

    starts: list[tuple[str, FloatArray, FloatArray]] = []
    if initial is not None:
        if isinstance(initial, tuple):
            R, d = np.asarray(initial[0], dtype=float), np.asarray(initial[1], dtype=float)
        else:
            T0 = np.asarray(initial, dtype=float)
            R, d = T0[:3, :3], T0[:3, 3]
        starts.append((GIVEN, R, d))
    for i, p in enumerate(prepared):
        if len(p.points) < 4:
            continue
        coplanar = _coplanar(p.points)
        # IPPE, not EPnP, beside SQPnP on a plane: it gives both of the plane's minima
        methods = (("SQPnP", cv2.SOLVEPNP_SQPNP),) + (
            () if coplanar else (("EPnP", cv2.SOLVEPNP_EPNP),)
        )
        for label, flag in methods:
            with contextlib.suppress(DegenerateGeometryError, cv2.error):
                starts.append((f"{label} on view {i}", *_single_view_pose(p, flag)))
        if not any(name == f"SQPnP on view {i}" for name, _, _ in starts):
            # OpenCV's iterative PnP, a local method, only where the global SQPnP failed
            with contextlib.suppress(DegenerateGeometryError, cv2.error):
                start = _single_view_pose(p, cv2.SOLVEPNP_ITERATIVE)
                starts.append((f"iterative PnP on view {i}", *start))
        if coplanar:
            with contextlib.suppress(cv2.error):
                starts += [
                    (f"IPPE pose {k + 1} on view {i}", R, d)
                    for k, (R, d) in enumerate(_planar_poses(p))
                ]
    planar = _coplanar(np.vstack([p.points for p in prepared]))
    if (len(prepared) > 1 and not planar) or not starts:
        with contextlib.suppress(DegenerateGeometryError, np.linalg.LinAlgError):
            starts.append(
                ("the linear generalized-camera pose", *_linear_generalized_pose(prepared))
            )
    if not starts:
        raise DegenerateGeometryError(
            "cannot find an initial pose: no view has 4 points and the rays do not determine a "
            "linear solution (need >= 6 non-coplanar points from more than one camera centre); "
            "give an initial pose"
        )
    return starts
