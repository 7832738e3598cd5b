"""Sketch: the operator side of Active Sketch — snapshots, primitives, macros, plans, the VCR."""

from __future__ import annotations

import msgspec
import numpy as np

from umbra.connectors import Input, Module, Output, UserError, param
from umbra.connectors.messages import CameraModel, Image, JointState, Pose, Scalar, Status, Text
from umbra.connectors.path_messages import VCR_BUSY, ToolPath, VcrAction, VcrCommand, VcrState
from umbra.connectors.ptu_messages import PtuCommand, PtuMode, PtuState
from umbra.connectors.sketch_messages import (
    Macro,
    SketchBox,
    SketchPrimitive,
    SketchReply,
    StereoSnapshot,
)
from umbra.modules.arm.arm_params import ArmParams
from umbra.modules.geometry.transforms import transform_from_xyz_rpy_deg
from umbra.modules.sketch.command_text import Command, parse
from umbra.modules.sketch.depth_check import depth_warnings
from umbra.modules.sketch.macros import MacroError, macro_keys, menu_for
from umbra.modules.sketch.path_check import PathLimits, plan_path
from umbra.modules.sketch.primitives import PrimitiveError, place_primitive, triad_box
from umbra.modules.sketch.session import Q_READY, Q_STOW
from umbra.modules.sketch.stereo import StereoNoise, StereoPair


class _SnapshotRefused(UserError):
    """The snapshot's own refusal: it ends a waiting snapshot."""


class _NotYet(_SnapshotRefused):
    """A snapshot that must wait: a camera is settling or has no frame to match its model."""


class Sketch(Module["Sketch.Params"]):
    """Active Sketch (LDRD report section 3) on the operator's side.

    Text commands (``modules/sketch/command_text.py``: aim, zoom, snapshot, place, plan, vcr)
    from the console, the CLI or a scripted operator. A snapshot freezes both images with both
    camera models (zoom included) and poses: it is refused while a PTU is slewing, within
    ``settle_time`` of an aim, a zoom or PTU motion, and until each camera has a frame newer
    than that and than its camera model (so image and model belong together): the snapshot is
    then taken as soon as they are, within ``snapshot_wait``, and replied to then. Placed
    primitives are constrained to the epipolar lines and triangulated with their covariance
    (``pixel_sigma``, ``handle_sigma`` along a featureless edge and the calibration sigmas); a
    primitive whose depth rests on where a handle sits along an edge that runs with the epipolar
    lines is flagged in the reply, with what to do (``modules/sketch/depth_check.py``); a
    triad's macro ``make_box`` sends the box it spans (scene geometry for the 3-D view, no
    motion). A plan is checked
    (reach, joint limits, singularities, speed) before it is sent, and refused while the player
    moves the arm (the plan starts from the arm's joints); only a path that passed is
    sent to the player; VCR commands go to the player for the current path. When a path starts
    playing the cameras are slewed to watch its goal. ``status.message`` holds the outcome of the
    last command and the macro menu of the last primitive.
    """

    TYPE = "Sketch"

    class Params(ArmParams):
        tool_xyz: list[float] = param(
            [0.0, 0.0, 0.14], "tool point in the flange", unit="m", min_length=3, max_length=3
        )
        tool_rpy_deg: list[float] = param(
            [0.0, 0.0, 0.0], "tool frame in the flange", unit="deg", min_length=3, max_length=3
        )
        world_frame: str = param("base", "frame of the 3-D points")
        pixel_sigma: float = param(0.5, "operator's placement error", unit="px", ge=0)
        handle_sigma: float = param(
            StereoNoise.handle_px,
            "operator's placement error along a featureless edge (sets the depth of a vertex "
            "whose edge runs along the epipolar lines)",
            unit="px",
            ge=0,
            le=500,
        )
        rotation_sigma: float = param(2e-4, "camera orientation error", unit="rad", ge=0)
        translation_sigma: float = param(2e-4, "camera position error", unit="m", ge=0)
        max_image_age: float = param(0.5, "snapshot: newest image at most this old", unit="s", gt=0)
        settle_time: float = param(
            0.2, "snapshot: after an aim, zoom or PTU motion, wait", unit="s", ge=0, le=5
        )
        snapshot_wait: float = param(
            3.0, "snapshot: wait at most this long for settled cameras", unit="s", ge=0, le=30
        )

    command = Input(Text, required=False, doc="operator commands (scripted operator, CLI)")
    console = Input(Text, required=False, doc="operator commands from the /sketch page")
    image_a = Input(Image, required=False, doc="camera a (left) frames")
    image_b = Input(Image, required=False, doc="camera b (right) frames")
    camera_a = Input(CameraModel, required=False, doc="model of camera a at its zoom")
    camera_b = Input(CameraModel, required=False, doc="model of camera b at its zoom")
    mount_a = Input(Pose, required=False, doc="T_world_mount of camera a's PTU")
    mount_b = Input(Pose, required=False, doc="T_world_mount of camera b's PTU")
    ptu_state_a = Input(PtuState, required=False, doc="PTU a angles (moving?)")
    ptu_state_b = Input(PtuState, required=False, doc="PTU b angles (moving?)")
    joint_state = Input(JointState, required=False, feedback=True, doc="the arm's joints")
    vcr_state = Input(VcrState, required=False, feedback=True, doc="the player's state")
    snapshot = Output(StereoSnapshot, events=True, doc="stereo snapshot pairs")
    primitive = Output(SketchPrimitive, events=True, doc="placed, triangulated primitives")
    box = Output(SketchBox, events=True, doc="boxes kept from triads (make_box)")
    path = Output(ToolPath, events=True, doc="checked paths (only those that passed)")
    plan_preview = Output(ToolPath, events=True, doc="every plan, passed or refused, for display")
    vcr = Output(VcrCommand, events=True, doc="VCR commands for the player")
    ptu_a = Output(PtuCommand, events=True, doc="PTU a commands")
    ptu_b = Output(PtuCommand, events=True, doc="PTU b commands")
    zoom_a = Output(Scalar, events=True, doc="zoom requests of camera a (to SONY)")
    zoom_b = Output(Scalar, events=True, doc="zoom requests of camera b (to SONY)")
    status = Output(
        Status,
        events=True,
        doc="a reply to each command: stage SketchReply (ok or refused), message, menu",
    )

    def start(self) -> None:
        p = self.params
        self.table = p.table
        self.T_flange_tool = transform_from_xyz_rpy_deg(p.tool_xyz, p.tool_rpy_deg)
        self.noise = StereoNoise(
            p.pixel_sigma, p.rotation_sigma, p.translation_sigma, handle_px=p.handle_sigma
        )
        self.limits = PathLimits()
        self.snapshots: dict[str, StereoSnapshot] = {}
        self.primitives: dict[str, SketchPrimitive] = {}
        self.paths: dict[str, ToolPath] = {}
        self.current_path = ""
        self._watch: dict[str, np.ndarray] = {}
        self._started_paths: set[str] = set()
        self._counts = {"commands": 0, "refused": 0}
        #: per camera, the last time its view changed (aim or zoom sent, its PTU seen moving)
        self._moved_at = {"a": float("-inf"), "b": float("-inf")}
        self._now = 0.0
        #: deadline of a snapshot waiting for the cameras to settle (None: none is waiting)
        self._snapshot_due: float | None = None

    def step(self, now: float) -> None:
        self._now = now
        for side, port in (("a", self.ptu_state_a), ("b", self.ptu_state_b)):
            unit = port.get(now)
            if unit is not None and port.fresh and unit.moving:
                self._moved_at[side] = now
        if self._snapshot_due is not None:
            self._reply(lambda: f"snapshot {self._snapshot(now).snapshot_id}", now)
        for port in (self.command, self.console):
            command = port.get(now)
            if command is not None and port.fresh:
                self._counts["commands"] += 1
                self._reply(lambda text=command.text: self._command(text, now), now)

    def _command(self, text: str, now: float) -> str:
        cmd = parse(text)
        if self._snapshot_due is not None and cmd.verb not in ("vcr", "snapshot"):
            raise UserError(f"{cmd.verb}: a snapshot is being taken; send it again after that")
        return self._run(cmd, now)

    def _reply(self, action, now: float) -> None:
        """Run a command and send its outcome; a snapshot that must wait for the cameras to
        settle is retried each tick (no reply yet) until ``snapshot_wait`` has passed."""
        pending = self._snapshot_due
        try:
            message = action()
        except _NotYet as exc:
            if pending is None:
                self._snapshot_due = now + self.params.snapshot_wait
            elif now >= pending:
                self._snapshot_due = None
                self._refuse(f"{exc} (waited {self.params.snapshot_wait:.1f} s)")
            return
        except _SnapshotRefused as exc:
            self._snapshot_due = None
            self._refuse(str(exc))
            return
        except (UserError, MacroError, PrimitiveError, ValueError) as exc:
            self._refuse(str(exc))
            return
        self.status.send(Status(stage=SketchReply.OK, message=message))

    def _refuse(self, message: str) -> None:
        self._counts["refused"] += 1
        self.status.send(Status(stage=SketchReply.REFUSED, message=message, reason=message))

    # -- commands -----------------------------------------------------------------------------
    def _run(self, cmd: Command, now: float) -> str:
        if cmd.verb == "aim":
            assert cmd.point is not None
            self._aim(cmd.point)
            if cmd.zoom is not None:
                self._zoom(cmd.zoom)
            return f"aiming at {np.round(cmd.point, 3).tolist()} m"
        if cmd.verb == "zoom":
            assert cmd.zoom is not None
            self._zoom(cmd.zoom)
            return f"zoom {cmd.zoom:.3f}"
        if cmd.verb == "snapshot":
            return f"snapshot {self._snapshot(now).snapshot_id}"
        if cmd.verb == "place":
            return self._place(cmd, now)
        if cmd.verb == "plan":
            return self._plan(cmd, now)
        return self._vcr(cmd, now)

    def _aim(self, point: np.ndarray) -> None:
        for out in (self.ptu_a, self.ptu_b):
            out.send(PtuCommand(mode=PtuMode.POINT, point=point, frame=self.params.world_frame))
        self._moved_at = {side: self._now for side in self._moved_at}

    def _zoom(self, zoom: float) -> None:
        self._moved_at = {side: self._now for side in self._moved_at}
        self.zoom_a.send(Scalar(value=zoom))
        self.zoom_b.send(Scalar(value=zoom))

    def _snapshot(self, now: float) -> StereoSnapshot:
        parts = []
        for side, image, model, mount, ptu in (
            ("a", self.image_a, self.camera_a, self.mount_a, self.ptu_state_a),
            ("b", self.image_b, self.camera_b, self.mount_b, self.ptu_state_b),
        ):
            frame, cam, pose, unit = image.get(now), model.get(now), mount.get(now), ptu.get(now)
            if frame is None or cam is None or pose is None:
                raise _SnapshotRefused(
                    f"snapshot: camera {side} has not delivered an image, a model and a PTU pose"
                )
            if image.age(now) > self.params.max_image_age:
                raise _SnapshotRefused(
                    f"snapshot: camera {side}'s image is {image.age(now):.2f} s old"
                )
            if unit is not None and unit.moving:
                raise _SnapshotRefused(
                    f"snapshot: PTU {side} is still slewing; wait until it stops"
                )
            settled = self._moved_at[side] + self.params.settle_time
            if now < settled:
                raise _NotYet(
                    f"snapshot: camera {side} moved {now - self._moved_at[side]:.2f} s ago; "
                    f"expected it still for {self.params.settle_time:.2f} s"
                )
            if image.received_at <= max(settled, model.received_at):
                raise _NotYet(
                    f"snapshot: camera {side} has no frame since its view or zoom last changed; "
                    "wait for the next frame"
                )
            parts.append((frame, cam, pose.matrix @ cam.T_mount_camera))
        (ia, ca, Ta), (ib, cb, Tb) = parts
        sid = f"snap{len(self.snapshots) + 1}"
        snap = StereoSnapshot.of_pair(
            now, sid, (ca, ia.pixels, Ta), (cb, ib.pixels, Tb), frame=self.params.world_frame
        )
        sent = self.snapshot.send(snap)  # dated by the oldest image it holds
        self.snapshots[sid] = sent
        self._snapshot_due = None  # taken: nothing waits any more
        return sent

    def _place(self, cmd: Command, now: float) -> str:
        if not self.snapshots:
            raise UserError("place: take a snapshot first")
        snap = self.snapshots[list(self.snapshots)[-1]]
        pid = f"{cmd.kind}{len(self.primitives) + 1}"
        pair = StereoPair.from_snapshot(snap)
        assert cmd.pixels_a is not None and cmd.pixels_b is not None  # parse() sets a place's
        prim = place_primitive(
            pair,
            cmd.kind,
            cmd.pixels_a,
            cmd.pixels_b,
            self.noise,
            primitive_id=pid,
            snapshot_id=snap.snapshot_id,
            stamp=now,
            frame=self.params.world_frame,
        )
        self.primitives[pid] = prim
        self.primitive.send(prim)
        menu = ", ".join(m for m, _ in menu_for(prim))
        sigma = np.sqrt(np.max(np.linalg.eigvalsh(prim.covariances), axis=1)) * 1e3
        warned = "".join(f"; WARNING {w}" for w in depth_warnings(pair, prim))
        return (
            f"{pid} placed (largest sigma {np.round(sigma, 2).tolist()} mm){warned}; macros: {menu}"
        )

    def _plan(self, cmd: Command, now: float) -> str:
        prim = None
        if cmd.primitive_id:
            prim = self.primitives.get(cmd.primitive_id)
            if prim is None:
                raise UserError(
                    f"plan: no primitive {cmd.primitive_id!r}; placed: {sorted(self.primitives)}"
                )
        if cmd.macro is None:
            raise UserError("plan: expected a macro")
        if cmd.macro == Macro.MAKE_BOX:
            return self._make_box(prim)
        state = self.joint_state.get(now)
        if state is None:
            raise UserError("plan: no joint state from the arm yet")
        vcr = self.vcr_state.get(now)
        if vcr is not None and vcr.mode in VCR_BUSY:
            raise UserError(
                f"plan: the arm is moving ({vcr.path_id} {vcr.mode}); pause it, then plan"
            )
        q = np.asarray(state.position, dtype=float)
        keys = macro_keys(
            cmd.macro,
            prim,
            self.table.fk(q, self.T_flange_tool),
            float(state.gripper),
            cmd.options,
            q_ready=Q_READY,
            q_stow=Q_STOW,
            camera_centre=self.snapshots[list(self.snapshots)[-1]].T_base_camera_a[:3, 3]
            if self.snapshots
            else None,
        )
        path = plan_path(
            keys,
            self.table,
            self.T_flange_tool,
            q,
            float(state.gripper),
            self.limits,
            path_id=f"path{len(self.paths) + 1}",
            stamp=now,
        )
        snapshot = self.snapshots.get(prim.snapshot_id) if prim is not None else None
        if snapshot is not None:  # as old as the images the primitive was placed in
            path = msgspec.structs.replace(path, origin=snapshot.origin)
        self.paths[path.path_id] = path
        self.plan_preview.send(path)
        if not path.ok:
            raise UserError(f"plan {cmd.macro}: refused: {path.reason}")
        watch = keys.watch
        if watch is None and len(path.T_base_tool):
            watch = np.asarray(path.T_base_tool[-1][:3, 3])  # canned motions: the tool's goal
        if watch is not None:
            self._watch[path.path_id] = watch
        self.current_path = path.path_id
        self.path.send(path)
        return (
            f"{path.path_id} ({cmd.macro}) checked: {len(path.s)} samples, "
            f"{path.checks.get('duration', 0.0):.1f} s at full speed"
        )

    def _make_box(self, prim: SketchPrimitive | None) -> str:
        """The triad's macro: its box is kept as scene geometry (no motion)."""
        if prim is None or prim.kind != "triad":
            raise UserError(f"make_box: expected a triad, got {prim.kind if prim else 'nothing'}")
        snap = self.snapshots.get(prim.snapshot_id)
        pair = StereoPair.from_snapshot(snap) if snap is not None else None
        box = triad_box(prim, pair=pair, noise=self.noise)
        self.box.send(box)
        size = np.round(box.size, 3).tolist()
        centre = np.round(box.T_base_box[:3, 3], 3).tolist()
        return f"box {box.box_id} kept: centre {centre} m, size {size} m"

    def _vcr(self, cmd: Command, now: float) -> str:
        assert cmd.action is not None  # the parser sets it on every vcr command
        if not self.current_path:
            raise UserError("vcr: plan a macro first")
        starts = (VcrAction.PLAY, VcrAction.RESUME)
        if cmd.action in starts and self.current_path not in self._started_paths:
            self._started_paths.add(self.current_path)
            watch = self._watch.get(self.current_path)
            if watch is not None:
                self._aim(watch)  # the report: cameras slew to watch the macro's goal
        self.vcr.send(
            VcrCommand(
                stamp=now,
                action=cmd.action,
                path_id=self.current_path,
                speed=cmd.speed or 0.0,
                s=cmd.s or 0.0,
            )
        )
        return f"vcr {cmd.action} {self.current_path}"

    def summary(self) -> dict[str, object]:
        return {
            **self._counts,
            "snapshots": len(self.snapshots),
            "primitives": sorted(self.primitives),
            "paths": sorted(self.paths),
        }
