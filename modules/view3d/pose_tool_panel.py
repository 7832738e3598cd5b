"""The camera-pose tool in the 3-D view (report section 5.5, Figures 20-21).

The operator takes snapshots with the camera whose mount is in doubt (each keeps the pose the
graph *believes*), then, pair by pair, clicks a calibration feature in a snapshot's image (the
click ray meets the image drawn on the frustum: a pixel) and the same feature on the model (the
ray meets the model's surface: a 3-D point). With three pairs or more, over one or several
snapshots taken at different PTU or arm poses, "Solve mount" finds the mount ``M`` (the graph's
static frame ``parent->child``, believed ``M0``) that best explains every click, with the
non-perspective n-point solver. Each snapshot's believed camera pose is split around the mount::

    T_world_camera(i) = T_world_parent(i) . M . T_child_camera(i)

* ``parent`` tied to the world by the static frames (a PTU's base ``base->ptu_left``): then
  ``T_world_parent`` is that static pose and ``T_child_camera(i) = (T_world_parent M0)^-1
  T_world_camera_believed(i)`` (the pan-tilt kinematics and the camera's mount in the head): the
  rays of different snapshots do not meet, the report's non-perspective case;
* otherwise ``parent`` moves (the arm's ``tool``, a PTU head) and ``child`` is the camera:
  ``T_world_parent(i) = T_world_camera_believed(i) M0^-1``, ``T_child_camera = I``.

Every click's reprojection residual is drawn on the images and listed in the panel. "Save"
writes the mount as a frames calibration file and a session file that ``umbra pose-tool``
solves the same way.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from umbra.modules.calib.camera_model import Intrinsics, PinholeCamera
from umbra.modules.calib.errors import CalibrationError
from umbra.modules.calib.pose_tool import MountResult, MountSnapshot, pose_error, solve_mount
from umbra.modules.calib.pose_tool_file import frames_text, session_text
from umbra.modules.geometry.transforms import invert_transform
from umbra.modules.view3d.geometry import pixel_of_ray_on_image, ray_hit


@dataclass
class Pair:
    """One calibration point: the snapshot, the clicked pixel (drawn image, px), the model point
    (world, m)."""

    snapshot_id: str
    pixel: np.ndarray
    point: np.ndarray | None = None


class PoseTool:
    """The pose tool's state and logic, apart from any widget (tested without a browser)."""

    def __init__(
        self,
        mount_parent: str,
        mount_child: str,
        T_parent_child: np.ndarray,
        image_depth: Callable[[str], float],
        T_world_parent: np.ndarray | None = None,
    ) -> None:
        """``T_parent_child``: the believed mount (4x4, m); ``T_world_parent``: the parent's
        static pose in the view's world, or None when the parent moves (see the module)."""
        self.parent = mount_parent
        self.child = mount_child
        self.T_parent_child = np.asarray(T_parent_child, dtype=float)
        self.T_world_parent = (
            None if T_world_parent is None else np.asarray(T_world_parent, dtype=float)
        )
        self.image_depth = image_depth
        self.pairs: list[Pair] = []
        self.result: MountResult | None = None
        self.result_ids: list[str] = []

    # -- clicks -----------------------------------------------------------------------------

    def click_image(
        self, origin, direction, snapshots: dict, prefer: str | None = None
    ) -> Pair | None:
        """A click ray on the snapshot images starts a new pair: on the image of snapshot
        ``prefer`` (the one the operator views from) when the ray meets it, else on the nearest
        image it meets (the images of snapshots taken a few degrees apart cross each other)."""
        best = None
        for snapshot_id, (_, frustum) in snapshots.items():
            depth = self.image_depth(snapshot_id)
            uv = pixel_of_ray_on_image(origin, direction, frustum, depth)
            if uv is None:
                continue
            point = frustum.points_from_pixels(uv[None], depth)[0]
            distance = float(np.linalg.norm(point - np.asarray(origin, dtype=float)))
            if snapshot_id == prefer:
                distance = -1.0
            if best is None or distance < best[0]:
                best = (distance, snapshot_id, uv)
        if best is None:
            return None
        pair = Pair(best[1], best[2])
        if self.pairs and self.pairs[-1].point is None:
            self.pairs[-1] = pair  # a second image click replaces an unpaired one
        else:
            self.pairs.append(pair)
        return pair

    def click_model(self, origin, direction, meshes) -> np.ndarray | None:
        """A click ray on the model: where it hits the surface completes the open pair."""
        if not self.pairs or self.pairs[-1].point is not None:
            return None
        hit = ray_hit(origin, direction, list(meshes))
        if hit is None:
            return None
        self.pairs[-1].point = hit.point
        return hit.point

    def complete_pairs(self) -> list[Pair]:
        return [p for p in self.pairs if p.point is not None]

    # -- solving ----------------------------------------------------------------------------

    def _mount_snapshots(self, snapshots: dict) -> tuple[list[MountSnapshot], list[str]]:
        by_id: dict[str, list[Pair]] = {}
        for pair in self.complete_pairs():
            by_id.setdefault(pair.snapshot_id, []).append(pair)
        out, ids = [], []
        for snapshot_id, pairs in by_id.items():
            snap, _ = snapshots[snapshot_id]
            # the clicked pixels are the image's own pixels (the image is stretched over the
            # drawn frustum), so the camera's own intrinsics map them to rays
            K = np.asarray(snap.K, dtype=float)
            camera = PinholeCamera(Intrinsics(K[0, 0], K[1, 1], K[0, 1], K[0, 2], K[1, 2]))
            T_believed = np.asarray(snap.T_world_camera, dtype=float)
            if self.T_world_parent is not None:  # a static parent: the chain after the mount
                T_world_parent = self.T_world_parent
                T_child_camera = invert_transform(T_world_parent @ self.T_parent_child) @ T_believed
            else:  # a moving parent, the child is the camera
                T_world_parent = T_believed @ invert_transform(self.T_parent_child)
                T_child_camera = np.eye(4)
            out.append(
                MountSnapshot(
                    camera,
                    np.array([p.point for p in pairs]),
                    np.array([p.pixel for p in pairs]),
                    T_world_parent,
                    T_child_camera,
                )
            )
            ids.append(snapshot_id)
        return out, ids

    def solve(self, snapshots: dict) -> MountResult:
        """The mount ``M`` (``result.T_parent_child``) from every complete pair, started at
        the believed mount.

        Every pair must come from snapshots of one camera: the correction is that camera's."""
        cameras = sorted({snapshots[p.snapshot_id][0].camera for p in self.complete_pairs()})
        if len(cameras) > 1:
            raise CalibrationError(
                f"the points are in snapshots of cameras {', '.join(cameras)}; one camera's "
                "mount is solved at a time (clear the points and click one camera's snapshots)"
            )
        mount_snapshots, ids = self._mount_snapshots(snapshots)
        self.result = solve_mount(mount_snapshots, self.T_parent_child)
        self.result_ids = ids
        return self.result

    def solved(self) -> MountResult:
        """The last solve's result; :class:`CalibrationError` before the first solve."""
        if self.result is None:
            raise CalibrationError("solve the mount first")
        return self.result

    def corrected_mount(self) -> np.ndarray:
        return self.solved().T_parent_child

    def change(self) -> tuple[float, float]:
        """How far the solved mount is from the believed one: (degrees, metres)."""
        angle, offset = pose_error(self.corrected_mount(), self.T_parent_child)
        return float(np.degrees(angle)), offset

    def residual_table(self) -> str:
        """The residual of every click, as a markdown table."""
        if self.result is None:
            return ""
        rows = ["| snapshot | pixel | residual px |", "|---|---|---|"]
        for snapshot_id, residuals in zip(self.result_ids, self.result.residuals, strict=True):
            pairs = [p for p in self.complete_pairs() if p.snapshot_id == snapshot_id]
            for pair, r in zip(pairs, residuals, strict=True):
                rows.append(
                    f"| {snapshot_id} | {pair.pixel[0]:.0f}, {pair.pixel[1]:.0f} | "
                    f"{float(np.linalg.norm(r)):.2f} |"
                )
        return "\n".join(rows)

    def save(self, folder: Path, snapshots: dict) -> list[Path]:
        """Write ``mount_<parent>_<child>.yaml`` (frames) and, when every snapshot has the same
        intrinsics, ``pose_tool_session.yaml`` (the clicks, for ``umbra pose-tool``)."""
        result = self.solved()
        corrected = result.T_parent_child
        folder.mkdir(parents=True, exist_ok=True)
        mount_path = folder / f"mount_{self.parent}_{self.child}.yaml"
        comment = (
            f"camera mount {self.parent}->{self.child} solved by the 3-D view's pose tool "
            f"(RMS {result.rms_px:.3f} px)"
        )
        mount_path.write_text(frames_text(self.parent, self.child, corrected, comment))
        mount_snapshots, ids = self._mount_snapshots(snapshots)
        Ks = [s.camera.K for s in mount_snapshots]
        if any(not np.allclose(K, Ks[0]) for K in Ks):
            return [mount_path]  # a session file holds one camera model (no zoom changes)
        points: dict[str, np.ndarray] = {}
        entries = []
        for snapshot, snapshot_id in zip(mount_snapshots, ids, strict=True):
            clicks = {}
            for k, (X, uv) in enumerate(zip(snapshot.points_world, snapshot.pixels, strict=True)):
                name = f"{snapshot_id}-{k + 1}".replace("/", "_")
                points[name] = X
                clicks[name] = (float(uv[0]), float(uv[1]))
            entries.append((snapshot.T_world_parent, snapshot.T_child_camera, clicks))
        session_path = folder / "pose_tool_session.yaml"
        session_path.write_text(
            session_text(
                self.parent,
                self.child,
                mount_snapshots[0].camera,
                points,
                entries,
                self.T_parent_child,
            )
        )
        return [mount_path, session_path]
