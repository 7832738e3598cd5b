"""What drawing the arm costs the simulated cameras, in the same run.

The shipped pick-up's 720p wrist camera (``graphs/tool_pickup.yaml``: 1280x720, fx 800,
photograph on the table, noise 3 grey levels) renders the scene from two true arm poses, with
and without the arm's faces (:mod:`umbra.modules.vision.arm_view`; on the wrist camera only the
fingers are in front of the lens): the start (camera 35 cm above the table) and near the grasp
(tool point 2 cm above the patch, fingers open). The Active Sketch camera (640x480) renders the
nominal scene with and without the arm. Frames alternate with and without, ``--frames`` each
(200), so both see the same load; the table gives the median and p95 step time and the ratio
with / without of the medians. The frames near the grasp are written to ``docs/images``.

    python benchmarks/bench_arm_render.py [--frames N] [--quick]
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.common import table, write_results  # noqa: E402
from umbra.modules.arm.arm_params import ArmParams  # noqa: E402
from umbra.modules.arm.arm_solids import arm_frames  # noqa: E402
from umbra.modules.geometry.transforms import rot_x  # noqa: E402
from umbra.modules.vision.arm_view import arm_in, arm_occluders, with_arm  # noqa: E402
from umbra.modules.vision.lighting import Lighting, Sensor  # noqa: E402
from umbra.modules.vision.scene import Scene  # noqa: E402
from umbra.modules.vision.sim_camera import CameraSpec, SimulatedCamera  # noqa: E402
from umbra.modules.vision.sketch_render import render_scene  # noqa: E402
from umbra.modules.world.ik import solve_ik  # noqa: E402
from umbra.modules.world.scene_objects import SketchScene  # noqa: E402
from umbra.modules.world.world import T_table_patch_of  # noqa: E402

DOCS = ROOT / "docs" / "images"
#: graphs/tool_pickup.yaml: frames, start joints, tool
T_TABLE_BASE = np.eye(4)
T_TABLE_BASE[2, 3] = -0.25
T_FLANGE_TOOL = np.eye(4)
T_FLANGE_TOOL[2, 3] = 0.14
T_TOOL_CAMERA = np.eye(4)
T_TOOL_CAMERA[2, 3] = -0.12
Q_START = np.radians([14.482, 45.603, -182.743, 0.0, -42.86, -165.518])
T_TABLE_PATCH = T_table_patch_of([0.63, -0.04], np.radians(20.0), 0.03)


def wrist_poses() -> dict[str, np.ndarray]:
    """Joint values: the start, and the tool 2 cm above the patch looking down at it."""
    table = ArmParams().table
    T_target = T_TABLE_PATCH @ rot_x(np.pi)  # tool z (approach) down into the patch
    T_target[2, 3] += 0.02
    T_base_target = np.linalg.inv(T_TABLE_BASE) @ T_target
    return {"start": Q_START, "near grasp": solve_ik(table, T_base_target, Q_START, T_FLANGE_TOOL)}


def time_wrist(q: np.ndarray, frames: int, name: str) -> dict[str, float]:
    table = ArmParams().table
    spec = CameraSpec.from_values(800, 800, 0, 640, 360, 1280, 720, [0, 0, 0, 0])
    scene = Scene(T_world_patch=T_TABLE_PATCH, background="photo")
    T_table_flange = T_TABLE_BASE @ table.fk(q)
    T_world_camera = T_table_flange @ T_FLANGE_TOOL @ T_TOOL_CAMERA
    matrices, children = arm_frames(table, q, T_FLANGE_TOOL, 1.0, T_TABLE_BASE)
    from umbra.connectors.messages import Poses

    poses = Poses(matrices=matrices, children=children, frame="table")
    camera, lighting, rng = SimulatedCamera(), Lighting(noise_sigma=3.0), np.random.default_rng(1)
    times: dict[bool, list[float]] = {False: [], True: []}
    frame = None
    for _ in range(frames):
        for arm in (False, True):
            t0 = time.perf_counter()
            shown = scene
            if arm:
                faces = arm_occluders(arm_in(poses, np.eye(4)), T_world_camera)
                shown = dataclasses.replace(scene, occluders=faces)
            rendered = camera.render(spec, shown, T_world_camera, lighting, rng)
            times[arm].append(time.perf_counter() - t0)
            if arm:
                frame = rendered
    assert frame is not None
    arm_px = int(np.count_nonzero(frame.labels == 3))
    cv2.imwrite(str(DOCS / f"wrist_camera_arm_{name.replace(' ', '_')}.png"), frame.image)
    return _row(times) | {"arm_pixels": arm_px, "patch_visible": frame.patch_visible_fraction}


def time_sketch(frames: int) -> dict[str, float]:
    table = ArmParams().table
    scene = SketchScene.nominal()
    objects = scene.message()
    q = np.radians([0.0, 45.6, -182.7, 0.0, -42.9, 0.0])
    matrices, children = arm_frames(table, q, T_FLANGE_TOOL, 1.0)
    from umbra.connectors.messages import Poses

    poses = Poses(matrices=matrices, children=children, frame="base")
    K = np.array([[700.0, 0, 320], [0, 700.0, 240], [0, 0, 1]])
    eye, target = np.array([-0.6, 0.5, 1.2]), np.array([0.45, 0.0, 0.35])
    z = (target - eye) / np.linalg.norm(target - eye)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    T_base_camera = np.eye(4)
    T_base_camera[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    T_base_camera[:3, 3] = eye
    rng = np.random.default_rng(2)
    sensor = Sensor((480, 640, 3))
    times: dict[bool, list[float]] = {False: [], True: []}
    image = None
    for _ in range(frames):
        for arm in (False, True):
            t0 = time.perf_counter()
            shown = with_arm(objects, arm_in(poses, np.eye(4))) if arm else objects
            pixels = render_scene(shown, K, T_base_camera, 640, 480, None, rng, 2.0, sensor)
            times[arm].append(time.perf_counter() - t0)
            if arm:
                image = pixels
    cv2.imwrite(str(DOCS / "sketch_camera_arm.png"), image)
    return _row(times)


def _row(times: dict[bool, list[float]]) -> dict[str, float]:
    without, with_ = np.array(times[False]) * 1e3, np.array(times[True]) * 1e3
    return {
        "without_p50_ms": float(np.median(without)),
        "without_p95_ms": float(np.percentile(without, 95)),
        "with_p50_ms": float(np.median(with_)),
        "with_p95_ms": float(np.percentile(with_, 95)),
        "ratio_p50": float(np.median(with_) / np.median(without)),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=200, help="frames each way (200)")
    parser.add_argument("--quick", action="store_true", help="20 frames each way")
    args = parser.parse_args()
    frames = 20 if args.quick else args.frames
    results: dict[str, dict[str, float]] = {}
    for name, q in wrist_poses().items():
        results[f"wrist 1280x720, {name}"] = time_wrist(q, frames, name)
    results["sketch camera 640x480"] = time_sketch(frames)
    header = ["camera, pose", "without p50/p95 ms", "with arm p50/p95 ms", "ratio", "arm px"]
    rows = [
        [
            name,
            f"{r['without_p50_ms']:.2f} / {r['without_p95_ms']:.2f}",
            f"{r['with_p50_ms']:.2f} / {r['with_p95_ms']:.2f}",
            f"{r['ratio_p50']:.3f}",
            r.get("arm_pixels", "-"),
        ]
        for name, r in results.items()
    ]
    print(table(rows, header))
    path = write_results("arm_render", {"frames": frames, "rows": results}, quick=args.quick)
    print(f"results: {path}")


if __name__ == "__main__":
    main()
