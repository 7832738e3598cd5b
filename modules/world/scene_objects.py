"""The Active Sketch scene: a pipe, a door on a hinge with a handle, a package and a flat surface
on and around the table in front of the arm (LDRD report section 3), with randomizable poses.

All in the arm's ``base`` frame (metres, radians; z up, the Puma's base on the floor), the
table top ``table_z`` above it. Each object knows its true geometry; the world judges macros
against it (:mod:`umbra.modules.world.sketch_world`), the renderer draws it
(:mod:`umbra.modules.vision.sketch_render`) from :meth:`SketchScene.solids`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from umbra.connectors.scene_messages import SceneObjects, SolidKind
from umbra.modules.geometry.transforms import rot_z

FloatArray = NDArray[np.float64]


def _pose(R: FloatArray, t: FloatArray) -> FloatArray:
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = t
    return T


def _frame_with_z(z_axis: FloatArray) -> FloatArray:
    """A rotation whose z axis is ``z_axis`` (unit)."""
    z = z_axis / np.linalg.norm(z_axis)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


@dataclass(frozen=True)
class Pipe:
    """A horizontal pipe on two cradles: axis through ``center`` (m) at ``yaw`` (rad, from x)."""

    center: FloatArray
    yaw: float
    radius: float = 0.02
    length: float = 0.30

    @property
    def axis(self) -> FloatArray:
        return np.array([np.cos(self.yaw), np.sin(self.yaw), 0.0])

    @property
    def ends(self) -> FloatArray:
        half = 0.5 * self.length * self.axis
        return np.stack([self.center - half, self.center + half])

    @property
    def top_ends(self) -> FloatArray:
        """The two ends of the pipe's top generatrix (what the operator sees and marks)."""
        return self.ends + np.array([0.0, 0.0, self.radius])


@dataclass(frozen=True)
class Door:
    """A cabinet door on a vertical hinge, facing the arm (-x), opening towards it.

    ``hinge`` (m): bottom point of the hinge axis; the closed panel runs from the hinge along
    -y for ``width``, its front face (towards the arm) in the plane x = hinge x, its back
    ``thickness`` behind it. ``angle`` (rad): opening, positive towards the arm (a rotation
    about -z: by the right-hand rule about the hinge line taken from its top to its bottom).
    The handle is a level bar along the panel, centred ``handle_offset`` along it from the
    hinge, standing ``handle_standoff`` in front of it on two posts, ``handle_height`` above
    the hinge's bottom.
    """

    hinge: FloatArray
    width: float = 0.26
    height: float = 0.40
    thickness: float = 0.02
    handle_offset: float = 0.18
    handle_standoff: float = 0.05
    handle_height: float = 0.22
    handle_length: float = 0.10
    handle_radius: float = 0.01
    angle: float = 0.0

    @property
    def R_base_panel(self) -> FloatArray:
        """Panel frame (a proper rotation, determinant +1): x along the panel from the hinge,
        y into the panel (from its front face to its back), z up; origin at ``hinge``."""
        R_closed = np.column_stack([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
        return rot_z(-self.angle)[:3, :3] @ R_closed

    @property
    def handle_center(self) -> FloatArray:
        R = self.R_base_panel
        return self.hinge + R @ np.array(
            [self.handle_offset, -self.handle_standoff, self.handle_height]
        )

    @property
    def handle_axis(self) -> FloatArray:
        """Unit direction of the handle bar (along the panel, away from the hinge)."""
        return self.R_base_panel[:, 0]

    @property
    def handle_rest_xy(self) -> FloatArray:
        """Horizontal offset (m) of the handle axis from the hinge with the door closed."""
        return replace(self, angle=0.0).handle_center[:2] - self.hinge[:2]

    @property
    def hinge_top(self) -> FloatArray:
        return self.hinge + np.array([0.0, 0.0, self.height])


@dataclass(frozen=True)
class Package:
    """A box on the table: ``center`` of its bottom face (m), ``yaw`` (rad) of its x axis,
    ``size`` (m). Its front face (towards the arm) is the -x face at zero yaw."""

    center: FloatArray
    yaw: float
    size: tuple[float, float, float] = (0.18, 0.22, 0.14)

    @property
    def front_bottom_edge(self) -> FloatArray:
        """The two ends of the front face's bottom edge (m, base)."""
        R = rot_z(self.yaw)[:3, :3]
        sx, sy, _ = self.size
        return np.stack(
            [self.center + R @ [-sx / 2, sy / 2, 0], self.center + R @ [-sx / 2, -sy / 2, 0]]
        )

    @property
    def outward(self) -> FloatArray:
        """Unit normal of the front face, pointing away from the box."""
        return rot_z(self.yaw)[:3, :3] @ np.array([-1.0, 0.0, 0.0])


@dataclass(frozen=True)
class Surface:
    """A flat rectangle on the table to scan: ``center`` (m), ``yaw`` (rad), ``size`` (m)."""

    center: FloatArray
    yaw: float
    size: tuple[float, float] = (0.16, 0.12)

    @property
    def corners(self) -> FloatArray:
        """The four corners (4, 3), counter-clockwise seen from above."""
        R = rot_z(self.yaw)[:3, :3]
        sx, sy = self.size[0] / 2, self.size[1] / 2
        local = [[-sx, -sy, 0], [sx, -sy, 0], [sx, sy, 0], [-sx, sy, 0]]
        return np.stack([self.center + R @ np.array(p, dtype=float) for p in local])


@dataclass(frozen=True)
class SketchScene:
    """The table and its objects (true poses)."""

    table_z: float
    pipe: Pipe
    door: Door
    package: Package
    surface: Surface

    @classmethod
    def nominal(cls, table_z: float = 0.25) -> SketchScene:
        """The layout of the shipped graph, before randomization."""
        return cls(
            table_z=table_z,
            pipe=Pipe(np.array([0.62, 0.0, table_z + 0.05]), np.radians(90.0)),
            door=Door(np.array([0.80, 0.36, table_z])),
            package=Package(np.array([0.74, -0.34, table_z]), 0.0),
            surface=Surface(np.array([0.48, -0.22, table_z + 0.001]), 0.0),
        )

    @classmethod
    def random(cls, rng: np.random.Generator, table_z: float = 0.25) -> SketchScene:
        """A randomized scene: each object moved and turned about the nominal layout."""
        n = cls.nominal(table_z)

        def shift(xy: float) -> FloatArray:
            return np.array([rng.uniform(-xy, xy), rng.uniform(-xy, xy), 0.0])

        return replace(
            n,
            pipe=replace(
                n.pipe,
                center=n.pipe.center + shift(0.04),
                yaw=n.pipe.yaw + rng.uniform(-0.4, 0.4),
            ),
            door=replace(n.door, hinge=n.door.hinge + shift(0.03)),
            package=replace(
                n.package,
                center=n.package.center + shift(0.03),
                yaw=rng.uniform(-0.25, 0.25),
            ),
            surface=replace(
                n.surface,
                center=n.surface.center + shift(0.03),
                yaw=rng.uniform(-0.3, 0.3),
            ),
        )

    def with_door_angle(self, angle: float) -> SketchScene:
        return replace(self, door=replace(self.door, angle=float(angle)))

    # -- solids for rendering and the 3-D view ------------------------------------------------
    def solids(
        self,
    ) -> list[tuple[str, SolidKind, FloatArray, FloatArray, tuple[int, int, int]]]:
        """(name, kind, T_base_solid, size, RGB) of every solid; see SceneObjects for sizes."""
        out = []
        tz = self.table_z
        out.append(
            (
                "table",
                SolidKind.BOX,
                _pose(np.eye(3), np.array([0.65, 0.0, tz - 0.02])),
                np.array([0.8, 1.3, 0.04]),
                (150, 130, 105),
            )
        )
        p = self.pipe
        R_pipe = _frame_with_z(p.axis)
        out.append(
            (
                "pipe",
                SolidKind.CYLINDER,
                _pose(R_pipe, p.center),
                np.array([p.radius, p.radius, p.length]),
                (200, 60, 40),
            )
        )
        for k, end in enumerate(p.ends):
            inner = end + 0.25 * p.length * p.axis * (1 if k == 0 else -1)
            out.append(
                (
                    f"cradle_{k}",
                    SolidKind.BOX,
                    _pose(rot_z(p.yaw)[:3, :3], np.array([inner[0], inner[1], tz + 0.0125])),
                    np.array([0.02, 0.06, 0.025]),
                    (90, 90, 100),
                )
            )
        d = self.door
        R = d.R_base_panel
        panel_center = d.hinge + R @ np.array([d.width / 2, d.thickness / 2, d.height / 2])
        out.append(
            (
                "door",
                SolidKind.BOX,
                _pose(R, panel_center),
                np.array([d.width, d.thickness, d.height]),
                (60, 110, 170),
            )
        )
        out.append(
            (
                "cabinet",
                SolidKind.BOX,
                _pose(np.eye(3), d.hinge + np.array([0.2, -d.width / 2, d.height / 2 - 0.01])),
                np.array([0.36, d.width, d.height - 0.02]),
                (120, 120, 125),
            )
        )
        out.append(
            (
                "handle",
                SolidKind.CYLINDER,
                _pose(_frame_with_z(d.handle_axis), d.handle_center),
                np.array([d.handle_radius, d.handle_radius, d.handle_length]),
                (230, 200, 40),
            )
        )
        for k in (-1, 1):
            post = d.hinge + R @ np.array(
                [d.handle_offset + k * 0.04, -d.handle_standoff / 2, d.handle_height]
            )
            out.append(
                (
                    f"handle_post_{k}",
                    SolidKind.BOX,
                    _pose(R, post),
                    np.array([0.012, d.handle_standoff, 0.012]),
                    (230, 200, 40),
                )
            )
        b = self.package
        out.append(
            (
                "package",
                SolidKind.BOX,
                _pose(rot_z(b.yaw)[:3, :3], b.center + np.array([0, 0, b.size[2] / 2])),
                np.array(b.size),
                (190, 150, 90),
            )
        )
        s = self.surface
        out.append(
            (
                "surface",
                SolidKind.BOX,
                _pose(rot_z(s.yaw)[:3, :3], s.center),
                np.array([s.size[0], s.size[1], 0.002]),
                (70, 170, 80),
            )
        )
        return out

    def message(self, stamp: float = 0.0, values: dict[str, float] | None = None) -> SceneObjects:
        """The solids as a :class:`SceneObjects` message."""
        solids = self.solids()
        return SceneObjects(
            stamp=stamp,
            names=tuple(s[0] for s in solids),
            kinds=tuple(s[1] for s in solids),
            poses=np.stack([s[2] for s in solids]),
            sizes=np.stack([s[3] for s in solids]),
            colors=np.array([s[4] for s in solids], dtype=np.uint8),
            values=dict(values or {}),
        )


def targets_from_objects(objects: SceneObjects) -> dict[str, FloatArray]:
    """Named true 3-D features (m, base) read from a :class:`SceneObjects` message, for a
    simulated operator's clicks: ``pipe`` (axis ends, 2 x 3), ``handle`` (bar ends), ``hinge``
    (top then bottom: right-hand rule opens the door towards the arm), ``surface`` (three
    corners a, b, c of the plane primitive), ``package_edge`` (front bottom edge), and the
    centres ``pipe_center``, ``handle_center``, ``hinge_center``, ``surface_center``,
    ``package_center``."""
    index = {name: i for i, name in enumerate(objects.names)}

    def solid(name: str) -> tuple[FloatArray, FloatArray]:
        if name not in index:
            raise KeyError(f"the scene has no {name!r}; it has {list(objects.names)}")
        i = index[name]
        return np.asarray(objects.poses[i], dtype=float), np.asarray(objects.sizes[i], dtype=float)

    out: dict[str, FloatArray] = {}
    for name in ("pipe", "handle"):
        T, size = solid(name)
        half = 0.5 * size[2] * T[:3, 2]
        out[name] = np.stack([T[:3, 3] - half, T[:3, 3] + half])
        out[f"{name}_center"] = T[:3, 3]
    T, size = solid("door")
    hinge_mid = T[:3, 3] - T[:3, :3] @ np.array([size[0] / 2, size[1] / 2, 0.0])
    out["hinge"] = np.stack(
        [
            hinge_mid + np.array([0.0, 0.0, size[2] / 2]),
            hinge_mid - np.array([0.0, 0.0, size[2] / 2]),
        ]
    )
    out["hinge_center"] = hinge_mid
    T, size = solid("surface")
    R, c = T[:3, :3], T[:3, 3]
    sx, sy = size[0] / 2, size[1] / 2
    out["surface"] = np.stack([c + R @ [sx, -sy, 0], c + R @ [-sx, -sy, 0], c + R @ [-sx, sy, 0]])
    out["surface_center"] = c
    T, size = solid("package")
    R, c = T[:3, :3], T[:3, 3] - [0.0, 0.0, size[2] / 2]
    out["package_edge"] = np.stack(
        [c + R @ [-size[0] / 2, size[1] / 2, 0], c + R @ [-size[0] / 2, -size[1] / 2, 0]]
    )
    out["package_center"] = c
    return out
