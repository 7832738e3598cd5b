"""Denavit-Hartenberg tables (standard DH) and forward kinematics.

Standard (distal) DH, as Paul and Corke's Robotics Toolbox use it: link ``i`` carries frame
``i`` at its distal end and ``A_i = Rot_z(theta_i) Trans_z(d_i) Trans_x(a_i) Rot_x(alpha_i)``.
Joint ``i`` moves about (revolute) or along (prismatic) ``z_{i-1}``. The joint variable ``q_i``
adds to the constant ``theta`` of a revolute joint or to the constant ``d`` of a prismatic one.

Frames: ``base`` is frame 0, ``flange`` is frame n (the mounting face of the last link), and an
optional ``T_flange_tool`` locates the tool point. Units: metres and radians (metres for a
prismatic joint variable); seconds for rates.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]

JOINT_KINDS = ("revolute", "prismatic")


class DHError(ValueError):
    """A DH table or a joint vector is not valid; the message says what and where."""


@dataclass(frozen=True)
class DHJoint:
    """One link of a standard DH table.

    Attributes:
        name: joint name (unique in the table), e.g. ``"j1"``.
        d: link offset along ``z_{i-1}`` (m); the constant part for a prismatic joint.
        a: link length along ``x_i`` (m).
        alpha: link twist about ``x_i`` (rad).
        theta: joint angle offset about ``z_{i-1}`` (rad), Corke's ``offset`` for a revolute
            joint; the fixed angle of a prismatic joint.
        kind: ``"revolute"`` or ``"prismatic"``.
        q_min, q_max: joint limits (rad or m).
        qd_max: rate limit, magnitude (rad/s or m/s).
    """

    name: str
    d: float = 0.0
    a: float = 0.0
    alpha: float = 0.0
    theta: float = 0.0
    kind: str = "revolute"
    q_min: float = -np.inf
    q_max: float = np.inf
    qd_max: float = np.inf

    def __post_init__(self) -> None:
        where = f"joint {self.name!r}"
        if not self.name:
            raise DHError("a joint needs a non-empty name")
        if self.kind not in JOINT_KINDS:
            raise DHError(f"{where}: kind must be revolute or prismatic, got {self.kind!r}")
        for label in ("d", "a", "alpha", "theta"):
            if not np.isfinite(getattr(self, label)):
                raise DHError(f"{where}: {label} must be finite, got {getattr(self, label)}")
        if not self.q_min < self.q_max:
            raise DHError(f"{where}: q_min {self.q_min} must be below q_max {self.q_max}")
        if not self.qd_max > 0:
            raise DHError(f"{where}: qd_max must be positive, got {self.qd_max}")


@dataclass(frozen=True)
class DHTable:
    """A serial arm: its DH joints in order from the base, with arrays for fast kinematics."""

    joints: tuple[DHJoint, ...]
    name: str = "arm"
    # Derived arrays (filled in __post_init__).
    names: tuple[str, ...] = field(init=False, repr=False)
    q_min: FloatArray = field(init=False, repr=False, compare=False)
    q_max: FloatArray = field(init=False, repr=False, compare=False)
    qd_max: FloatArray = field(init=False, repr=False, compare=False)
    revolute: NDArray[np.bool_] = field(init=False, repr=False, compare=False)
    _d: FloatArray = field(init=False, repr=False, compare=False)
    _a: FloatArray = field(init=False, repr=False, compare=False)
    _theta: FloatArray = field(init=False, repr=False, compare=False)
    _cos_alpha: FloatArray = field(init=False, repr=False, compare=False)
    _sin_alpha: FloatArray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        joints = tuple(self.joints)
        if not joints:
            raise DHError(f"arm {self.name!r} has no joints")
        names = tuple(j.name for j in joints)
        duplicates = sorted({n for n in names if names.count(n) > 1})
        if duplicates:
            raise DHError(f"arm {self.name!r}: joint names must be unique, repeated: {duplicates}")
        alpha = np.array([j.alpha for j in joints])
        values = {
            "joints": joints,
            "names": names,
            "q_min": np.array([j.q_min for j in joints]),
            "q_max": np.array([j.q_max for j in joints]),
            "qd_max": np.array([j.qd_max for j in joints]),
            "revolute": np.array([j.kind == "revolute" for j in joints]),
            "_d": np.array([j.d for j in joints]),
            "_a": np.array([j.a for j in joints]),
            "_theta": np.array([j.theta for j in joints]),
            "_cos_alpha": np.cos(alpha),
            "_sin_alpha": np.sin(alpha),
        }
        for key, value in values.items():
            if isinstance(value, np.ndarray):
                value.setflags(write=False)
            object.__setattr__(self, key, value)

    @property
    def n(self) -> int:
        """Number of joints."""
        return len(self.joints)

    def check_q(self, q: ArrayLike) -> FloatArray:
        """``q`` as a float vector of this arm's length, or :class:`DHError`."""
        q = np.asarray(q, dtype=float).reshape(-1)
        if q.shape != (self.n,):
            raise DHError(f"arm {self.name!r} has {self.n} joints, got {q.shape[0]} joint values")
        if not np.all(np.isfinite(q)):
            raise DHError(f"joint values must be finite, got {q.tolist()}")
        return q

    def link_transforms(self, q: ArrayLike) -> FloatArray:
        """``(n, 4, 4)`` link transforms ``A_i = T_{i-1}_{i}`` at joint values ``q``."""
        q = self.check_q(q)
        theta = self._theta + np.where(self.revolute, q, 0.0)
        d = self._d + np.where(self.revolute, 0.0, q)
        ct, st = np.cos(theta), np.sin(theta)
        ca, sa = self._cos_alpha, self._sin_alpha
        A = np.zeros((self.n, 4, 4))
        A[:, 0, 0] = ct
        A[:, 0, 1] = -st * ca
        A[:, 0, 2] = st * sa
        A[:, 0, 3] = self._a * ct
        A[:, 1, 0] = st
        A[:, 1, 1] = ct * ca
        A[:, 1, 2] = -ct * sa
        A[:, 1, 3] = self._a * st
        A[:, 2, 1] = sa
        A[:, 2, 2] = ca
        A[:, 2, 3] = d
        A[:, 3, 3] = 1.0
        return A

    def frames(self, q: ArrayLike) -> FloatArray:
        """``(n + 1, 4, 4)``: ``T_base_i`` for ``i = 0 .. n`` (``T_base_0`` is the identity)."""
        A = self.link_transforms(q)
        T = np.empty((self.n + 1, 4, 4))
        T[0] = np.eye(4)
        for i in range(self.n):
            T[i + 1] = T[i] @ A[i]
        return T

    def fk(self, q: ArrayLike, T_flange_tool: ArrayLike | None = None) -> FloatArray:
        """``T_base_flange`` at ``q``, or ``T_base_tool`` when ``T_flange_tool`` is given."""
        A = self.link_transforms(q)
        T = A[0]
        for i in range(1, self.n):
            T = T @ A[i]
        if T_flange_tool is not None:
            T = T @ np.asarray(T_flange_tool, dtype=float)
        return T

    def limit_margin(self, q: ArrayLike) -> FloatArray:
        """Distance (rad or m) of each joint from its nearer limit; negative when outside."""
        q = self.check_q(q)
        return np.minimum(q - self.q_min, self.q_max - q)


#: The Puma 560's shoulder height: floor mounting surface to the shoulder axis, 26.45 in (m).
PUMA560_SHOULDER_HEIGHT_M = 26.45 * 0.0254


def puma560() -> DHTable:
    """The Puma 560 as Corke's Robotics Toolbox (Python) models it: standard DH, SI units.

    ``d = (0.67183, 0, 0.15005, 0.4318, 0, 0)``, ``a = (0, 0.4318, 0.0203, 0, 0, 0)``,
    ``alpha = (pi/2, 0, -pi/2, pi/2, -pi/2, 0)``, no offsets; base frame on the floor mounting
    surface below the shoulder (d1 = 26.45 in = 0.67183 m, :data:`PUMA560_SHOULDER_HEIGHT_M`;
    Corke's toolbox rounds it to 0.6718). Joint limits are Corke's (degrees:
    +-160, -45..225, -225..45, -110..170, +-100, +-266). Rate limits are nominal values of the
    order of the Puma 560's top joint speeds (rad/s: 1.4, 1.3, 2.1, 4.0, 4.2, 4.0); set your
    own for a real arm.
    """
    d = (PUMA560_SHOULDER_HEIGHT_M, 0.0, 0.15005, 0.4318, 0.0, 0.0)
    a = (0.0, 0.4318, 0.0203, 0.0, 0.0, 0.0)
    alpha = (np.pi / 2, 0.0, -np.pi / 2, np.pi / 2, -np.pi / 2, 0.0)
    limits_deg = ((-160, 160), (-45, 225), (-225, 45), (-110, 170), (-100, 100), (-266, 266))
    rates = (1.4, 1.3, 2.1, 4.0, 4.2, 4.0)
    joints = tuple(
        DHJoint(
            name=f"j{i + 1}",
            d=d[i],
            a=a[i],
            alpha=alpha[i],
            q_min=float(np.radians(limits_deg[i][0])),
            q_max=float(np.radians(limits_deg[i][1])),
            qd_max=rates[i],
        )
        for i in range(6)
    )
    return DHTable(joints=joints, name="puma560")
