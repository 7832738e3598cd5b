"""The 3-D view's scene: snapshots, boxes and sketched primitives, saved to a file that reloads.

A scene file is JSON (``scene.json``) beside a folder of PNG images (``scene.json.images/``)::

    {"format": "umbra-scene", "version": 1, "frame": "base",
     "snapshots": [{"id": "s1", "camera": "cam_left", "T_world_camera": [[...4x4...]],
                    "K": [[...3x3...]], "width": 640, "height": 480, "image": "s1.png"}],
     "boxes": [{"id": "box1", "T_world_box": [[...]], "size": [0.3, 0.2, 0.1]}],
     "primitives": [{"id": "p1", "kind": "line", "points": [[x, y, z], ...],
                     "edges": [[0, 1]]}]}

Metres, in the scene's ``frame``. Saving writes a new file and renames it over the old one, so
a run stopped mid-save leaves the previous scene. A bad file is a ``UserError`` that names the
file, the item and what was expected; images are never pickled, only PNG.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import msgspec
import numpy as np
from numpy.typing import NDArray

from umbra.connectors.errors import UserError
from umbra.connectors.sketch_messages import PrimitiveKind
from umbra.modules.geometry.transforms import is_rigid

FORMAT = "umbra-scene"
VERSION = 1
PRIMITIVE_KINDS = tuple(str(kind) for kind in PrimitiveKind)
MAX_ITEMS = 10_000


@dataclass(eq=False)
class SceneSnapshot:
    """A picture kept in the scene: camera name, pose ``T_world_camera`` (4x4, m), intrinsics
    ``K`` (3x3, px), image size (px) and the BGR image."""

    id: str
    camera: str
    T_world_camera: NDArray[np.float64]
    K: NDArray[np.float64]
    image: NDArray[np.uint8]

    @property
    def width(self) -> int:
        return int(self.image.shape[1])

    @property
    def height(self) -> int:
        return int(self.image.shape[0])


@dataclass(eq=False)
class SceneBox:
    """A box placed by a triad: centre and axes ``T_world_box`` (4x4, m), edge lengths (m)."""

    id: str
    T_world_box: NDArray[np.float64]
    size: NDArray[np.float64]


@dataclass(eq=False)
class ScenePrimitive:
    """A sketched primitive: ``kind`` (point, line, plane, triad), vertices ``(n, 3)`` m, and
    the vertex pairs drawn as edges."""

    id: str
    kind: str
    points: NDArray[np.float64]
    edges: NDArray[np.int64]

    def plane_corners(self) -> NDArray[np.float64] | None:
        """A plane's parallelogram ``(4, 3)``: vertices a, b, c and ``a + c - b``."""
        if self.kind != "plane" or len(self.points) != 3:
            return None
        a, b, c = self.points
        return np.array([a, b, c, a + c - b])


@dataclass(eq=False)
class Scene:
    """Everything the operator added to the model, by id (a new item with an old id replaces)."""

    frame: str = "base"
    snapshots: dict[str, SceneSnapshot] = field(default_factory=dict)
    boxes: dict[str, SceneBox] = field(default_factory=dict)
    primitives: dict[str, ScenePrimitive] = field(default_factory=dict)

    def count(self) -> int:
        return len(self.snapshots) + len(self.boxes) + len(self.primitives)


# -- the file's shape (msgspec checks types and names; the code below checks values) ----------


class _Snapshot(msgspec.Struct, forbid_unknown_fields=True):
    id: str
    camera: str
    T_world_camera: list[list[float]]
    K: list[list[float]]
    width: int
    height: int
    image: str


class _Box(msgspec.Struct, forbid_unknown_fields=True):
    id: str
    T_world_box: list[list[float]]
    size: list[float]


class _Primitive(msgspec.Struct, forbid_unknown_fields=True):
    id: str
    kind: str
    points: list[list[float]]
    edges: list[list[int]] = []


class _File(msgspec.Struct, forbid_unknown_fields=True):
    format: str
    version: int
    frame: str
    snapshots: list[_Snapshot] = []
    boxes: list[_Box] = []
    primitives: list[_Primitive] = []


def images_dir(path: Path) -> Path:
    """The folder of a scene file's images."""
    return path.with_name(path.name + ".images")


def _safe_name(item_id: str) -> str:
    keep = "".join(c if c.isalnum() or c in "-_." else "_" for c in item_id)
    return keep.strip(".") or "item"


def save_scene(scene: Scene, path: str | Path) -> Path:
    """Write the scene (JSON + PNG images) atomically; returns the file's path."""
    path = Path(path)
    folder = images_dir(path)
    folder.mkdir(parents=True, exist_ok=True)
    snapshots = []
    for snap in scene.snapshots.values():
        name = _safe_name(snap.id) + ".png"
        target = folder / name
        if not target.exists():  # a snapshot's image never changes once taken
            ok, png = cv2.imencode(".png", snap.image)
            if not ok:
                raise UserError(f"{path}: error: cannot encode the image of snapshot {snap.id!r}")
            tmp = target.with_suffix(".png.tmp")
            tmp.write_bytes(png.tobytes())
            os.replace(tmp, target)
        snapshots.append(
            {
                "id": snap.id,
                "camera": snap.camera,
                "T_world_camera": np.asarray(snap.T_world_camera).tolist(),
                "K": np.asarray(snap.K).tolist(),
                "width": snap.width,
                "height": snap.height,
                "image": name,
            }
        )
    data = {
        "format": FORMAT,
        "version": VERSION,
        "frame": scene.frame,
        "snapshots": snapshots,
        "boxes": [
            {"id": b.id, "T_world_box": b.T_world_box.tolist(), "size": b.size.tolist()}
            for b in scene.boxes.values()
        ],
        "primitives": [
            {"id": p.id, "kind": p.kind, "points": p.points.tolist(), "edges": p.edges.tolist()}
            for p in scene.primitives.values()
        ],
    }
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(data, indent=1))
    os.replace(tmp, path)
    return path


def _matrix(value: list[list[float]], shape: tuple[int, int], where: str) -> np.ndarray:
    try:
        array = np.array(value, dtype=float)
    except ValueError:
        raise ValueError(f"{where}: expected a {shape[0]}x{shape[1]} matrix of numbers") from None
    if array.shape != shape:
        raise ValueError(f"{where}: expected a {shape[0]}x{shape[1]} matrix, found {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{where}: numbers must be finite")
    return array


def _pose(value: list[list[float]], where: str) -> np.ndarray:
    T = _matrix(value, (4, 4), where)
    if not is_rigid(T, 1e-6):
        raise ValueError(
            f"{where}: expected a rigid transform (rotation, translation, last row 0 0 0 1)"
        )
    return T


def load_scene(path: str | Path) -> Scene:
    """Read a scene file and its images; ``UserError`` saying what is wrong and where."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as error:
        raise UserError(f"{path}: error: cannot read the scene file: {error.strerror}") from None
    try:
        parsed = msgspec.json.decode(raw, type=_File)
    except msgspec.DecodeError as error:
        raise UserError(f"{path}: error: not a scene file: {error}") from None
    if parsed.format != FORMAT or parsed.version != VERSION:
        raise UserError(
            f"{path}: error: expected format {FORMAT!r} version {VERSION}, found "
            f"{parsed.format!r} version {parsed.version}"
        )
    total = len(parsed.snapshots) + len(parsed.boxes) + len(parsed.primitives)
    if total > MAX_ITEMS:
        raise UserError(f"{path}: error: {total} items, more than the limit {MAX_ITEMS}")
    scene = Scene(frame=parsed.frame)
    try:
        for i, s in enumerate(parsed.snapshots):
            where = f"snapshots[{i}] ({s.id!r})"
            K = _matrix(s.K, (3, 3), f"{where}.K")
            if not (K[0, 0] > 0 and K[1, 1] > 0):
                raise ValueError(f"{where}.K: focal lengths must be positive")
            image_path = images_dir(path) / s.image
            if Path(s.image).name != s.image:
                raise ValueError(f"{where}.image: expected a file name, found {s.image!r}")
            image = cv2.imread(str(image_path), cv2.IMREAD_COLOR)
            if image is None:
                raise ValueError(f"{where}.image: cannot read {image_path}")
            if image.shape[:2] != (s.height, s.width):
                raise ValueError(
                    f"{where}.image: expected {s.width}x{s.height} px, found "
                    f"{image.shape[1]}x{image.shape[0]}"
                )
            T = _pose(s.T_world_camera, f"{where}.T_world_camera")
            # IMREAD_COLOR decodes to 8-bit BGR: the dtype converts nothing.
            pixels = np.asarray(image, dtype=np.uint8)
            scene.snapshots[s.id] = SceneSnapshot(s.id, s.camera, T, K, pixels)
        for i, b in enumerate(parsed.boxes):
            where = f"boxes[{i}] ({b.id!r})"
            size = np.array(b.size, dtype=float)
            if size.shape != (3,) or not np.all(np.isfinite(size)) or np.any(size <= 0):
                raise ValueError(f"{where}.size: expected 3 positive numbers, found {b.size}")
            scene.boxes[b.id] = SceneBox(b.id, _pose(b.T_world_box, f"{where}.T_world_box"), size)
        for i, p in enumerate(parsed.primitives):
            where = f"primitives[{i}] ({p.id!r})"
            if p.kind not in PRIMITIVE_KINDS:
                raise ValueError(
                    f"{where}.kind: expected one of {PRIMITIVE_KINDS}, found {p.kind!r}"
                )
            points = np.array(p.points, dtype=float) if p.points else np.zeros((0, 3))
            if points.ndim != 2 or points.shape[1] != 3 or not np.all(np.isfinite(points)):
                raise ValueError(f"{where}.points: expected finite [x, y, z] points")
            edges = np.array(p.edges, dtype=np.int64).reshape(-1, 2)
            if len(edges) and (edges.min() < 0 or edges.max() >= len(points)):
                raise ValueError(f"{where}.edges: vertex index outside 0..{len(points) - 1}")
            scene.primitives[p.id] = ScenePrimitive(p.id, p.kind, points, edges)
    except ValueError as error:
        raise UserError(f"{path}: error: {error}") from None
    return scene
