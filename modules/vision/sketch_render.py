"""Render the Active Sketch scene (boxes and cylinders) for a simulated camera.

A painter's algorithm over flat-shaded faces: each solid is cut into planar polygons (a box's six
faces; a cylinder's side strips and two caps), faces turned away from the camera are dropped,
the rest are drawn far to near with OpenCV. Good enough for an operator to see the objects and
for the tests to check where they appear; not a photometric model. Pixels are the pixels the
lens shows (distortion applied to the polygon vertices). Metres, base frame.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from umbra.connectors.scene_messages import SceneObjects, SolidKind
from umbra.modules.calib.distortion import distort_points
from umbra.modules.vision.lighting import Lighting, Sensor

FloatArray = NDArray[np.float64]
_LIGHT = np.array([0.3, -0.4, 0.87]) / np.linalg.norm([0.3, -0.4, 0.87])
_CYLINDER_SIDES = 24
_NEAR = 0.05  # [m] faces closer than this to the camera are not drawn


def _box_faces(T: FloatArray, size: FloatArray) -> list[tuple[FloatArray, FloatArray]]:
    h = 0.5 * np.asarray(size, dtype=float)
    faces = []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            u, v = [a for a in range(3) if a != axis]
            corners = []
            for du, dv in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                p = np.zeros(3)
                p[axis], p[u], p[v] = sign * h[axis], du * h[u], dv * h[v]
                corners.append(p)
            normal = np.zeros(3)
            normal[axis] = sign
            faces.append((np.stack(corners) @ T[:3, :3].T + T[:3, 3], T[:3, :3] @ normal))
    return faces


def _cylinder_faces(T: FloatArray, size: FloatArray) -> list[tuple[FloatArray, FloatArray]]:
    r, half = float(size[0]), 0.5 * float(size[2])
    angles = np.linspace(0.0, 2 * np.pi, _CYLINDER_SIDES, endpoint=False)
    ring = np.column_stack([r * np.cos(angles), r * np.sin(angles), np.zeros_like(angles)])
    R, t = T[:3, :3], T[:3, 3]
    bottom = (ring - [0, 0, half]) @ R.T + t
    top = (ring + np.array([0.0, 0.0, half])) @ R.T + t
    faces = [(bottom[::-1], -R[:, 2]), (top, R[:, 2])]
    for i in range(_CYLINDER_SIDES):
        j = (i + 1) % _CYLINDER_SIDES
        mid = 0.5 * (angles[i] + angles[j] + (2 * np.pi if j == 0 else 0.0))
        normal = R @ np.array([np.cos(mid), np.sin(mid), 0.0])
        faces.append((np.stack([bottom[i], bottom[j], top[j], top[i]]), normal))
    return faces


def render_scene(
    objects: SceneObjects,
    K: FloatArray,
    T_base_camera: FloatArray,
    width: int,
    height: int,
    dist: FloatArray | None = None,
    rng: np.random.Generator | None = None,
    noise_sigma: float = 0.0,
    sensor: Sensor | None = None,
) -> NDArray[np.uint8]:
    """A BGR image (height x width x 3, uint8) of ``objects`` seen by the camera.

    Args:
        K: 3 x 3 intrinsics (px); ``dist``: OpenCV distortion or None.
        T_base_camera: the camera's pose (4 x 4, m) in the objects' frame.
        noise_sigma: Gaussian pixel noise (grey levels) drawn from ``rng`` by the simulated
            cameras' one sensor model (:class:`~umbra.modules.vision.lighting.Sensor`); pass one as
            ``sensor`` to reuse its buffers and noise bank from frame to frame.
    """
    import cv2

    T_camera_base = np.linalg.inv(np.asarray(T_base_camera, dtype=float))
    eye = np.asarray(T_base_camera, dtype=float)[:3, 3]
    image = np.empty((height, width, 3), dtype=np.uint8)
    image[:] = (70, 75, 80)  # the floor, BGR
    faces: list[tuple[float, NDArray[np.int32], tuple[int, int, int]]] = []
    scale = 16  # fixed-point sub-pixel drawing (cv2 shift = 4)
    for kind, T, size, rgb in zip(
        objects.kinds, objects.poses, objects.sizes, objects.colors, strict=True
    ):
        build = {SolidKind.BOX: _box_faces, SolidKind.CYLINDER: _cylinder_faces}[kind]
        for corners, normal in build(np.asarray(T, dtype=float), np.asarray(size, dtype=float)):
            if normal @ (corners.mean(axis=0) - eye) >= 0.0:
                continue  # turned away
            cam = corners @ T_camera_base[:3, :3].T + T_camera_base[:3, 3]
            if np.any(cam[:, 2] < _NEAR):
                continue
            uv = cam[:, :2] / cam[:, 2:3] @ K[:2, :2].T + K[:2, 2]
            if dist is not None and np.any(dist):
                uv = distort_points(uv, K, dist)
            shade = 0.45 + 0.55 * max(0.0, float(normal @ _LIGHT))
            blue, green, red = (int(min(255, c * shade)) for c in (rgb[2], rgb[1], rgb[0]))
            bgr = (blue, green, red)
            faces.append((float(cam[:, 2].mean()), np.round(uv * scale).astype(np.int32), bgr))
    for _, polygon, bgr in sorted(faces, key=lambda f: -f[0]):
        cv2.fillPoly(image, [polygon], bgr, lineType=cv2.LINE_AA, shift=4)
    if noise_sigma > 0 and rng is not None:
        if sensor is None or sensor.shape != image.shape:
            sensor = Sensor(image.shape)
        image = sensor.apply(image, Lighting(noise_sigma=noise_sigma), rng)
    return image
