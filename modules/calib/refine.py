"""Full calibration from 3-D/2-D pairs: DLT, decomposition, then nonlinear refinement.

The refinement (the "Levenberg-Marquardt" step suggested at the end of Appendix A) minimizes the
pixel reprojection error over all camera parameters at once: ``fx, fy, skew, u0, v0``, the
distortion ``k1, k2, p1, p2`` (optionally ``k3``), and the pose ``R, d``. ``R`` is updated by a
rotation vector about the current estimate (``R = exp([w]_x) R0``), so it stays a rotation.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from umbra.modules.calib.camera_model import DISTORTION_NAMES, Intrinsics, PinholeCamera
from umbra.modules.calib.decompose import decompose_camera_matrix
from umbra.modules.calib.dlt import check_correspondences, dlt_camera_matrix, rms
from umbra.modules.calib.errors import DegenerateGeometryError
from umbra.modules.calib.rotations import rotation_from_vector

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class CalibrationResult:
    """A fitted camera, its reprojection residuals (pixels, ``(n, 2)``) and their RMS (pixels).

    ``standard_errors`` maps each fitted parameter to its one-sigma error from the Gauss-Newton
    covariance ``s^2 (J^T J)^-1`` at the minimum, ``s^2`` the residual variance per pixel
    coordinate (``SSR / (2n - p)``): ``fx fy [skew] u0 v0`` px, distortion terms unitless,
    ``rx ry rz`` rad (a rotation about the fitted ``R``, reference frame: ``R = exp([r]_x) R_fit``),
    ``dx dy dz`` m; the Jacobian is taken at the fitted camera. Empty for the linear (DLT only)
    camera.
    """

    camera: PinholeCamera
    residuals: FloatArray
    rms_px: float
    linear_rms_px: float
    evaluations: int
    standard_errors: dict[str, float] = field(default_factory=dict)
    #: sum of squared residuals (px^2) and number of fitted parameters, for model selection
    ssr_px2: float = float("nan")
    parameter_count: int = 0

    def interval_95(self) -> dict[str, float]:
        """Half-widths of the parameters' 95 % intervals: Student's t quantile at the residuals'
        degrees of freedom (``2n - p``: the noise is estimated from them) times the standard
        errors, in their units."""
        from scipy.stats import t as student

        dof = self.residuals.size - self.parameter_count
        if dof <= 0:
            return {name: float("nan") for name in self.standard_errors}
        factor = float(student.ppf(0.975, dof))
        return {name: factor * se for name, se in self.standard_errors.items()}


#: Which distortion terms a fit refines: the first ``n`` of ``DISTORTION_NAMES`` (0, 2, 4 or 5),
#: or the names of the terms themselves (``("p1", "p2")``: tangential terms alone).
DistortionTerms = int | tuple[str, ...]


def term_indices(distortion_terms: DistortionTerms) -> tuple[int, ...]:
    """Positions in ``DISTORTION_NAMES`` of the refined distortion terms (ValueError for a count
    other than 0, 2, 4, 5 or an unknown name)."""
    if isinstance(distortion_terms, int):
        if distortion_terms not in (0, 2, 4, 5):
            raise ValueError(f"distortion_terms must be 0, 2, 4 or 5, got {distortion_terms}")
        return tuple(range(distortion_terms))
    unknown = [name for name in distortion_terms if name not in DISTORTION_NAMES]
    if unknown:
        raise ValueError(f"distortion terms must be among {DISTORTION_NAMES}, got {unknown}")
    return tuple(sorted(DISTORTION_NAMES.index(name) for name in set(distortion_terms)))


def parameter_names(distortion_terms: DistortionTerms, fix_skew: bool) -> tuple[str, ...]:
    """Names of the refined parameters, in the order of the packed vector."""
    head = ("fx", "fy") + (() if fix_skew else ("skew",)) + ("u0", "v0")
    terms = tuple(DISTORTION_NAMES[i] for i in term_indices(distortion_terms))
    return head + terms + ("rx", "ry", "rz", "dx", "dy", "dz")


def _standard_errors(jac: FloatArray, r: FloatArray, names: tuple[str, ...]) -> dict[str, float]:
    dof = r.size - len(names)
    if dof <= 0:
        return {name: float("nan") for name in names}
    variance = float(r @ r) / dof
    try:
        covariance = variance * np.linalg.inv(jac.T @ jac)
    except np.linalg.LinAlgError:
        return {name: float("inf") for name in names}
    return dict(zip(names, np.sqrt(np.abs(np.diag(covariance))).tolist(), strict=True))


def _unpack(
    params: FloatArray, base_R: FloatArray, terms: tuple[int, ...], fix_skew: bool
) -> PinholeCamera:
    fx, fy = float(params[0]), float(params[1])
    i = 2
    skew = 0.0 if fix_skew else float(params[i])
    i += 0 if fix_skew else 1
    u0, v0 = float(params[i]), float(params[i + 1])
    i += 2
    distortion = np.zeros(5)
    distortion[list(terms)] = params[i : i + len(terms)]
    i += len(terms)
    R = rotation_from_vector(params[i : i + 3]) @ base_R
    d = params[i + 3 : i + 6]
    return PinholeCamera(Intrinsics(fx, fy, skew, u0, v0), R, d, distortion)


def _pack(camera: PinholeCamera, terms: tuple[int, ...], fix_skew: bool) -> FloatArray:
    f = camera.intrinsics
    head = [f.fx, f.fy] + ([] if fix_skew else [f.skew]) + [f.u0, f.v0]
    return np.concatenate([head, camera.distortion[list(terms)], np.zeros(3), camera.d]).astype(
        float
    )


def refine_camera(
    camera: PinholeCamera,
    points: ArrayLike,
    pixels: ArrayLike,
    distortion_terms: DistortionTerms = 4,
    fix_skew: bool = False,
) -> CalibrationResult:
    """Refine every parameter of ``camera`` on measured pixels (``scipy.optimize.least_squares``).

    Args:
        camera: initial guess (e.g. from :func:`calibrate`'s linear step).
        points: ``(n, 3)`` points in metres, reference frame.
        pixels: ``(n, 2)`` measured (distorted) pixels.
        distortion_terms: 0 (none), 2 (k1 k2), 4 (k1 k2 p1 p2, the report's model) or 5 (+k3),
            or the names of the terms to refine (``("p1", "p2")``); the others are zero.
        fix_skew: hold skew at 0 (OpenCV's model) instead of fitting the report's ``fxy``.
    """
    from scipy.optimize import least_squares

    terms = term_indices(distortion_terms)
    X, uv = check_correspondences(points, pixels)
    unknowns = 6 + (4 if fix_skew else 5) + len(terms)
    if 2 * len(X) < unknowns:
        raise DegenerateGeometryError(
            f"refining {unknowns} parameters needs at least {(unknowns + 1) // 2} pairs, "
            f"got {len(X)}"
        )
    base_R = camera.R

    def residuals(params: FloatArray) -> FloatArray:
        model = _unpack(params, base_R, terms, fix_skew)
        return (model.project(X) - uv).ravel()

    start = _pack(camera, terms, fix_skew)
    solution = least_squares(residuals, start, method="lm", x_scale="jac", xtol=1e-12, ftol=1e-12)
    fitted = _unpack(solution.x, base_R, terms, fix_skew)
    if fitted.intrinsics.fx <= 0 or fitted.intrinsics.fy <= 0:
        raise DegenerateGeometryError("refinement diverged to a non-positive focal length")
    r = solution.fun.reshape(-1, 2)
    start_r = residuals(start).reshape(-1, 2)
    names = parameter_names(distortion_terms, fix_skew)
    jacobian = _jacobian_at(fitted, X, terms, fix_skew)
    return CalibrationResult(
        camera=fitted,
        residuals=r,
        rms_px=rms(np.linalg.norm(r, axis=1)),
        linear_rms_px=rms(np.linalg.norm(start_r, axis=1)),
        evaluations=int(solution.nfev),
        standard_errors=_standard_errors(jacobian, solution.fun, names),
        ssr_px2=float(solution.fun @ solution.fun),
        parameter_count=len(names),
    )


def _jacobian_at(
    camera: PinholeCamera, X: FloatArray, terms: tuple[int, ...], fix_skew: bool
) -> FloatArray:
    """The residuals' Jacobian at the fitted ``camera`` in the packed parameters, the rotation
    taken about the fitted ``R`` itself (``R = exp([w]_x) R_fit`` at ``w = 0``), so that the
    standard errors of ``rx ry rz`` are those of a rotation about it. Central differences, with
    steps of 1e-6 of each parameter's size (1e-7 rad for the rotation)."""
    base_R = camera.R
    x0 = _pack(camera, terms, fix_skew)
    steps = np.maximum(1e-6 * np.abs(x0), 1e-7)
    columns = []
    for k, h in enumerate(steps):
        ahead, behind = x0.copy(), x0.copy()
        ahead[k] += h
        behind[k] -= h
        forward = _unpack(ahead, base_R, terms, fix_skew).project(X)
        backward = _unpack(behind, base_R, terms, fix_skew).project(X)
        columns.append(((forward - backward) / (2.0 * h)).ravel())
    return np.column_stack(columns)


def linear_camera(points: ArrayLike, pixels: ArrayLike) -> PinholeCamera:
    """The DLT camera (no distortion), decomposed into intrinsics and extrinsics."""
    intrinsics, R, d = decompose_camera_matrix(dlt_camera_matrix(points, pixels))
    return PinholeCamera(intrinsics, R, d)


def calibrate(
    points: ArrayLike,
    pixels: ArrayLike,
    distortion_terms: DistortionTerms = 4,
    fix_skew: bool = False,
    refine: bool = True,
) -> CalibrationResult:
    """Calibrate one camera from ``n >= 6`` non-coplanar points (metres) and measured pixels.

    DLT with Hartley normalization, Appendix B decomposition, then (if ``refine``) nonlinear
    refinement of all parameters including distortion. Without ``refine`` the result is the
    linear camera and its residuals.
    """
    X, uv = check_correspondences(points, pixels)
    camera = linear_camera(X, uv)
    if fix_skew:
        f = camera.intrinsics
        camera = PinholeCamera(Intrinsics(f.fx, f.fy, 0.0, f.u0, f.v0), camera.R, camera.d)
    if refine:
        return refine_camera(camera, X, uv, distortion_terms, fix_skew)
    r = camera.project(X) - uv
    error = rms(np.linalg.norm(r, axis=1))
    return CalibrationResult(camera, r, error, error, 0)
