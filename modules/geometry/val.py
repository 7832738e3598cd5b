"""VAL locations ``(X, Y, Z, O, A, T)`` of the Rochester Puma, to and from 4x4 transforms.

Reconstruction (Rochester guide, sections 3, 7 and 9; the printed section 7 formula is damaged):

Section 3.2 gives the meaning of the angles: "rotate by -O around (the current) X, then by A
around the new Y, then by T around the new Z". With Paul's post-multiplication for moves in the
current frame that is the rotation ``B(O, A, T) = Rot_x(-O) Rot_y(A) Rot_z(T)``. The damaged
section 7 line reads ``TOOL(Loc) = Rot_z(-90) Rot_y(90) Rot_x(-O) Rot_y(A) Rot_z(T) Trans(X,Y,Z)``.
(X, Y, Z) is the TOOL origin in LAB, so the translation belongs in front, not at the end, and
the *absolute* location of TOOL in LAB is::

    T_lab_tool = Trans(X, Y, Z) @ Rot_z(-90) @ Rot_y(90) @ B(O, A, T)

``Rot_z(-90) Rot_y(90)`` has columns ``(-Z, X, -Y)`` of LAB: it is exactly the orientation of
T6 at zero joint angles (section 3.2). An absolute VAL location is therefore the pose relative
to a reference frame at the LAB origin oriented as T6 at rest. A *relative* location (TOOL
relative to T6, e.g. NULLTOOL or FLANGE) is ``Trans(X, Y, Z) @ B(O, A, T)``, with no prefix.

This is the only reading under which every identity in the guide holds (each is a test in
``tests/geometry/test_val_identities.py``):

1. T6 at rest has X along LAB -Z, Y along LAB X, Z along LAB -Y (section 3.2).
2. NULLTOOL = (0,0,0,90,-90,0) relative to T6 turns T6 at rest into axes parallel to LAB
   (``B(90, -90, 0) = Rot_z(-90) Rot_y(90)`` transposed). Had relative locations carried the
   prefix too, NULLTOOL would be the identity and TOOL would stay T6-oriented.
3. At rest the reported location is (650, 190, 975, 90, -90, 0) (Fig. 1, section 13.3): with the
   prefix, ``B(90, -90, 0)`` undoes it and TOOL is parallel to LAB, agreeing with 2. Without the
   prefix, (90, -90, 0) would describe a tool that is not parallel to LAB.
4. FLANGE = T6 @ (0,0,0,-180,0,-90): at rest its Z is LAB Y (out of the head), Y is LAB -Z
   (down) and X is LAB X (right), as section 3.3 says; it also equals NULLTOOL @ A8 with
   ``A8 = Rot_x(-90)`` (section 5, Table 1).
5. The product of the five rotations is the matrix D printed in section 9 (row 1, column 0
   prints ``-S_O S_T``; the product and the section 9 identities need ``+S_O S_T``).
6. The section 9 inverse: ``S_T D20 + C_T D21 = 0``; ``-S_A = D22``;
   ``A = atan2(-D22, S_T D21 - C_T D20)``; ``O = atan2(S_T D10 + C_T D11, S_T D00 + C_T D01)``.
   The printed ``T = atan2(D21, D20)`` lost a sign: ``D20 = -C_A C_T``, ``D21 = C_A S_T``, so
   ``T = atan2(D21, -D20)`` (the branch with ``C_A >= 0``, A in [-90, 90] degrees, which also
   holds INIT_A = -90).

Gimbal lock (A = +-90 degrees, ``C_A = 0``): D20 = D21 = 0 and only O - T (A = +90) or O + T
(A = -90) is determined. We then set T = 0 and the section 9 formula for O, which does not
divide by ``C_A``, gives the O that reproduces the rotation exactly. The forward rotation uses
scipy's intrinsic ``"XYZ"`` Euler sequence ``(-O, A, T)``; the inverse uses the section 9
formulas (cross-checked against scipy in the tests).

Units: SI inside (metres, radians). ``..._mm_deg`` functions take and return VAL's millimetres
and degrees, the guide's user-facing units.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from umbra.modules.geometry.transforms import transform_from_rotation_translation

FloatArray = NDArray[np.float64]

#: Rotation of T6 in LAB at zero joint angles: columns X6 = -Z, Y6 = +X, Z6 = -Y (section 3.2).
#: It equals ``Rot_z(-90) Rot_y(90)``, the prefix of absolute VAL locations.
R_LAB_T6_AT_REST: FloatArray = Rotation.from_euler("ZY", [-90.0, 90.0], degrees=True).as_matrix()

#: NULLTOOL, VAL's default TOOL relative to T6 (mm, deg).
NULLTOOL_LOC_MM_DEG: tuple[float, ...] = (0.0, 0.0, 0.0, 90.0, -90.0, 0.0)
#: FLANGE relative to T6 (mm, deg), section 3.3.
FLANGE_LOC_MM_DEG: tuple[float, ...] = (0.0, 0.0, 0.0, -180.0, 0.0, -90.0)
#: Location of TOOL = NULLTOOL at zero joint angles, section 13.3 (INIT_X ... INIT_T; mm, deg).
INIT_LOC_MM_DEG: tuple[float, ...] = (650.0, 190.13, 975.0, 90.0, -90.0, 0.0)

#: Below this ``hypot(D20, D21)`` (= |cos A|) the location is treated as gimbal-locked: T = 0.
GIMBAL_TOLERANCE = 1e-9


class ValLocationError(ValueError):
    """A VAL location or transform has the wrong shape or is not finite."""


def _as_location(location: ArrayLike) -> FloatArray:
    loc = np.asarray(location, dtype=float).reshape(-1)
    if loc.shape != (6,) or not np.all(np.isfinite(loc)):
        raise ValLocationError(
            f"a VAL location is 6 finite numbers (X,Y,Z,O,A,T), got {location!s}"
        )
    return loc


def oat_rotation(o: float, a: float, t: float) -> FloatArray:
    """``B(O, A, T) = Rot_x(-O) Rot_y(A) Rot_z(T)`` (3x3; angles in radians)."""
    return Rotation.from_euler("XYZ", [-o, a, t]).as_matrix()


def oat_from_rotation(B: ArrayLike) -> tuple[float, float, float]:
    """``(O, A, T)`` in radians with ``oat_rotation(O, A, T) == B`` (section 9, A in [-pi/2, pi/2]).

    ``D`` of section 9 is ``R_LAB_T6_AT_REST @ B``; the formulas are applied to that D.
    """
    B = np.asarray(B, dtype=float)
    if B.shape != (3, 3):
        raise ValLocationError(f"a rotation is 3x3, got shape {B.shape}")
    D = R_LAB_T6_AT_REST @ B
    return _oat_from_d(D)


def _oat_from_d(D: FloatArray) -> tuple[float, float, float]:
    if np.hypot(D[2, 0], D[2, 1]) < GIMBAL_TOLERANCE:
        t = 0.0
    else:
        t = float(np.arctan2(D[2, 1], -D[2, 0]))
    st, ct = np.sin(t), np.cos(t)
    a = float(np.arctan2(-D[2, 2], st * D[2, 1] - ct * D[2, 0]))
    o = float(np.arctan2(st * D[1, 0] + ct * D[1, 1], st * D[0, 0] + ct * D[0, 1]))
    return o, a, t


def transform_from_relative_location(location: ArrayLike) -> FloatArray:
    """Transform of a *relative* VAL location (e.g. TOOL in T6): ``Trans(X,Y,Z) @ B(O,A,T)``.

    Args:
        location: (X, Y, Z) metres, (O, A, T) radians.
    """
    x, y, z, o, a, t = _as_location(location)
    return transform_from_rotation_translation(oat_rotation(o, a, t), (x, y, z))


def relative_location_from_transform(T: ArrayLike) -> FloatArray:
    """Inverse of :func:`transform_from_relative_location`: (X, Y, Z) m, (O, A, T) rad."""
    T = _as_transform(T)
    o, a, t = oat_from_rotation(T[:3, :3])
    return np.array([*T[:3, 3], o, a, t])


def transform_from_location(location: ArrayLike) -> FloatArray:
    """``T_lab_tool`` of an absolute VAL location (X, Y, Z metres; O, A, T radians).

    ``Trans(X, Y, Z) @ Rot_z(-90) @ Rot_y(90) @ Rot_x(-O) @ Rot_y(A) @ Rot_z(T)``.
    """
    x, y, z, o, a, t = _as_location(location)
    return transform_from_rotation_translation(R_LAB_T6_AT_REST @ oat_rotation(o, a, t), (x, y, z))


def location_from_transform(T_lab_tool: ArrayLike) -> FloatArray:
    """VAL location (X, Y, Z metres; O, A, T radians) of ``T_lab_tool`` by section 9.

    At gimbal lock (A = +-pi/2) T is set to 0 and O absorbs the free rotation.
    """
    T = _as_transform(T_lab_tool)
    o, a, t = _oat_from_d(T[:3, :3])
    return np.array([*T[:3, 3], o, a, t])


def _as_transform(T: ArrayLike) -> FloatArray:
    T = np.asarray(T, dtype=float)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise ValLocationError(f"a transform is a finite 4x4 matrix, got shape {T.shape}")
    return T


def _si_from_mm_deg(location_mm_deg: ArrayLike) -> FloatArray:
    loc = _as_location(location_mm_deg)
    return np.concatenate([loc[:3] / 1000.0, np.radians(loc[3:])])


def _mm_deg_from_si(location: FloatArray) -> FloatArray:
    return np.concatenate([location[:3] * 1000.0, np.degrees(location[3:])])


def transform_from_location_mm_deg(location_mm_deg: ArrayLike) -> FloatArray:
    """``T_lab_tool`` (metres) of an absolute VAL location in VAL's units (mm, degrees)."""
    return transform_from_location(_si_from_mm_deg(location_mm_deg))


def location_mm_deg_from_transform(T_lab_tool: ArrayLike) -> FloatArray:
    """Absolute VAL location (mm, degrees) of ``T_lab_tool`` (metres)."""
    return _mm_deg_from_si(location_from_transform(T_lab_tool))


def transform_from_relative_location_mm_deg(location_mm_deg: ArrayLike) -> FloatArray:
    """Transform (metres) of a relative VAL location in mm and degrees (e.g. NULLTOOL in T6)."""
    return transform_from_relative_location(_si_from_mm_deg(location_mm_deg))


def relative_location_mm_deg_from_transform(T: ArrayLike) -> FloatArray:
    """Relative VAL location (mm, degrees) of a transform (metres)."""
    return _mm_deg_from_si(relative_location_from_transform(T))


def T_lab_t6_at_rest(location_of_nulltool_mm_deg: ArrayLike = INIT_LOC_MM_DEG) -> FloatArray:
    """T6 in LAB at zero joint angles, from the at-rest TOOL location (NULLTOOL; mm, deg).

    ``T6 = TOOL @ NULLTOOL^-1``; with the guide's INIT location this has the section 3.2 axes.
    """
    T_lab_tool = transform_from_location_mm_deg(location_of_nulltool_mm_deg)
    T_t6_tool = transform_from_relative_location_mm_deg(NULLTOOL_LOC_MM_DEG)
    return T_lab_tool @ np.linalg.inv(T_t6_tool)
