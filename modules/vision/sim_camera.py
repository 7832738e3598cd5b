"""The simulated wrist camera as a device: renders the patch scene for a camera model and pose,
and the scheduled faults of the failure-injection trials.

Keeps one :class:`~umbra.modules.vision.scene.SceneRenderer` per camera model (building one solves
the distortion maps, about a tenth of a second at 640x480), so a camera whose model changes
(a zoom) costs that each time its intrinsics change.

A :class:`SceneFault` changes the scene from a time on: an occluder slides over the patch, the
patch disappears, or a second patch of the same color appears against it. (A frozen frame
grabber is the camera module's business: it stops rendering.) Frames and units as in
:mod:`umbra.modules.vision.scene`: metres, seconds, the patch's own frame for the fault geometry.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from umbra.modules.calib.camera_model import Intrinsics
from umbra.modules.geometry.transforms import transform_points
from umbra.modules.vision.lighting import Lighting
from umbra.modules.vision.polygon import signed_area
from umbra.modules.vision.scene import (
    RGB,
    SIDE_AXES,
    Occluder,
    RenderedFrame,
    Scene,
    SceneRenderer,
    distractor_touching,
    patch_image_outline,
)

FloatArray = NDArray[np.float64]
FaultKind = Literal["none", "occluder", "remove_patch", "distractor", "freeze", "lag"]
PatchSide = Literal["+x", "-x", "+y", "-y"]

FAULT_KINDS: tuple[str, ...] = ("none", "occluder", "remove_patch", "distractor", "freeze", "lag")
#: The occluder's leading edge starts this far outside the patch [m].
OCCLUDER_GAP_M = 0.005
#: The occluder overhangs both sides of the patch by this much, and its leading edge stops this
#: far past the far side of the patch, where it stays [m].
OCCLUDER_MARGIN_M = 0.01
#: Height of the occluder above the patch plane, along the patch's z axis [m].
OCCLUDER_LIFT_M = 0.002
#: Tolerance on the fault time, so that a clock that sums steps reaches it on time [s].
_TIME_EPS_S = 1e-9


def occluder_over_patch(
    T_world_patch: FloatArray,
    patch_size_m: tuple[float, float],
    side: PatchSide,
    travel_m: float,
    gap_m: float = OCCLUDER_GAP_M,
    margin_m: float = OCCLUDER_MARGIN_M,
    lift_m: float = OCCLUDER_LIFT_M,
) -> FloatArray:
    """World corners (4 x 3) of a flat slab sliding over the patch from its ``side``.

    The slab lies ``lift_m`` above the patch plane (along the patch's z axis), overhangs the
    patch across its path by ``margin_m`` on each side, and starts with its leading edge
    ``gap_m`` outside the patch side ``side``; after moving ``travel_m`` [m] towards the patch it
    covers ``travel_m - gap_m`` of the patch (clipped to 0 .. the patch's extent). The leading
    edge stops ``margin_m`` past the opposite side, so the patch then stays covered. The slab is
    as long as the patch plus twice ``margin_m`` plus ``gap_m``, so its trailing edge is behind
    the patch once the patch is covered.
    """
    if travel_m < 0:
        raise ValueError(f"occluder travel must be >= 0, got {travel_m}")
    ax, ay = SIDE_AXES[side]
    w, h = patch_size_m
    half_along = 0.5 * (w if ax else h)
    half_across = 0.5 * (h if ax else w) + margin_m
    lead = max(half_along + gap_m - travel_m, -(half_along + margin_m))
    tail = lead + 2.0 * (half_along + margin_m) + gap_m
    along = np.array([ax, ay])
    across = np.array([-ay, ax])
    local = [
        along * a + across * c
        for a, c in (
            (lead, -half_across),
            (tail, -half_across),
            (tail, half_across),
            (lead, half_across),
        )
    ]
    points = np.column_stack([np.array(local), np.full(4, lift_m)])
    return transform_points(np.asarray(T_world_patch, dtype=np.float64), points)


@dataclass(frozen=True)
class SceneFault:
    """A fault scheduled ``at_s`` seconds [s] after the camera's first frame.

    ``kind``: ``occluder`` (a flat slab of color ``rgb`` slides over the patch from its
    ``side`` at ``speed_mps`` [m/s] in the patch plane, starting just outside it, see
    :func:`occluder_over_patch`), ``remove_patch`` (the patch is gone, the tool stays),
    ``distractor`` (a second patch of the same color and size lies against the patch side
    ``side``), ``freeze`` (the scene is unchanged; the camera stops rendering), ``lag`` (the
    scene is unchanged; the camera delivers frames of the past, see ``DigiCam``) or ``none``.
    """

    kind: FaultKind = "none"
    at_s: float = 3.0
    speed_mps: float = 0.05
    side: PatchSide = "+y"
    rgb: RGB = (225, 180, 150)

    def begun(self, elapsed_s: float) -> bool:
        """Whether the fault is on ``elapsed_s`` seconds after the camera's first frame."""
        return self.kind != "none" and elapsed_s >= self.at_s - _TIME_EPS_S

    def apply(self, scene: Scene, since_s: float) -> Scene:
        """The scene ``since_s`` seconds after the fault began (unchanged for none/freeze)."""
        if self.kind == "remove_patch":
            return dataclasses.replace(scene, patch_present=False)
        if self.kind == "distractor":
            T = distractor_touching(scene.T_world_patch, scene.patch_size_m, self.side)
            return dataclasses.replace(scene, distractors=(*scene.distractors, T))
        if self.kind == "occluder":
            travel = self.speed_mps * max(since_s, 0.0)
            polygon = occluder_over_patch(
                scene.T_world_patch, scene.patch_size_m, self.side, travel
            )
            occluder = Occluder(polygon=polygon, frame="world", rgb=self.rgb)
            return dataclasses.replace(scene, occluders=(*scene.occluders, occluder))
        return scene


@dataclass(frozen=True)
class CameraSpec:
    """Intrinsics (pixels, with the image size) and distortion ``(k1, k2, p1, p2, k3)`` of the
    simulated camera."""

    intrinsics: Intrinsics
    distortion: tuple[float, float, float, float, float]

    @classmethod
    def from_values(
        cls,
        fx: float,
        fy: float,
        skew: float,
        u0: float,
        v0: float,
        width: int,
        height: int,
        dist: ArrayLike,
    ) -> CameraSpec:
        coefficients = np.zeros(5)
        given = np.asarray(dist, dtype=float).ravel()
        if given.size not in (0, 4, 5):
            raise ValueError(f"distortion needs 4 or 5 coefficients, got {given.size}")
        coefficients[: given.size] = given
        k1, k2, p1, p2, k3 = (float(c) for c in coefficients)
        return cls(
            Intrinsics(
                float(fx), float(fy), float(skew), float(u0), float(v0), int(width), int(height)
            ),
            (k1, k2, p1, p2, k3),
        )


class SimulatedCamera:
    """Renders frames of a :class:`Scene` through the camera of the latest :class:`CameraSpec`."""

    def __init__(self) -> None:
        self._renderer: SceneRenderer | None = None
        self._spec: CameraSpec | None = None
        self.renderers_built = 0

    def render(
        self,
        spec: CameraSpec,
        scene: Scene,
        T_world_camera: NDArray[np.float64],
        lighting: Lighting,
        rng: np.random.Generator,
    ) -> RenderedFrame:
        """One frame with its ground truth (see :meth:`SceneRenderer.render`)."""
        if self._renderer is None or spec != self._spec:
            self._renderer = SceneRenderer(spec.intrinsics, spec.distortion)
            self._spec = spec
            self.renderers_built += 1
        return self._renderer.render(scene, T_world_camera, lighting, rng)

    def patch_outline(
        self,
        spec: CameraSpec,
        scene: Scene,
        T_world_camera: NDArray[np.float64],
        per_edge: int = 16,
    ) -> tuple[FloatArray, float]:
        """The patch outline in the distorted image (4 ``per_edge`` x 2 px, as
        :attr:`RenderedFrame.patch_polygon`) and the share of its area inside the image, without
        rendering (occlusion is not known). Empty and 0 when the patch is absent or behind."""
        T_camera_world = np.asarray(np.linalg.inv(T_world_camera), dtype=np.float64)
        polygon = patch_image_outline(
            scene, T_camera_world, spec.intrinsics, spec.distortion, per_edge
        )
        if polygon is None:
            return np.empty((0, 2)), 0.0
        area = abs(signed_area(polygon))
        if area <= 0:
            return polygon, 0.0
        inside = _clip_to_box(
            polygon, (-0.5, -0.5, spec.intrinsics.width - 0.5, spec.intrinsics.height - 0.5)
        )
        return polygon, min(abs(signed_area(inside)) / area, 1.0) if len(inside) >= 3 else 0.0


def _clip_to_box(polygon: FloatArray, box: tuple[float, float, float, float]) -> FloatArray:
    """Sutherland-Hodgman clip of a closed polygon (N x 2) to ``box`` (u0, v0, u1, v1)."""
    u0, v0, u1, v1 = box
    # Each half-plane as (axis, bound, keep-below).
    for axis, bound, below in ((0, u0, False), (0, u1, True), (1, v0, False), (1, v1, True)):
        if len(polygon) == 0:
            break
        out: list[FloatArray] = []
        count = len(polygon)
        for i in range(count):
            a, b = polygon[i], polygon[(i + 1) % count]
            a_in = a[axis] <= bound if below else a[axis] >= bound
            b_in = b[axis] <= bound if below else b[axis] >= bound
            if a_in:
                out.append(a)
            if a_in != b_in:
                t = (bound - a[axis]) / (b[axis] - a[axis])
                out.append(a + t * (b - a))
        polygon = np.array(out).reshape(-1, 2)
    return polygon
