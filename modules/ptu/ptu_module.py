"""PTU: a simulated pan-tilt unit that carries a camera and aims it on command."""

from __future__ import annotations

import numpy as np

from umbra.connectors import Input, Module, Output, Parameters, UserError, param
from umbra.connectors.messages import DEVICE_OK, CameraModel, Pose
from umbra.connectors.ptu_messages import PtuCommand, PtuMode, PtuState
from umbra.modules.calib.camera_message import pinhole_from_message
from umbra.modules.ptu.ptu_model import PtuGeometry, PtuLimitError, aim_in_base
from umbra.modules.ptu.sim_ptu import SimPtu


class Ptu(Module["Ptu.Params"]):
    """Simulated pan-tilt unit (rate- and acceleration-limited slewing).

    Commands: angles (pan, tilt) or a 3-D point in ``world_frame`` to aim at. Without a camera
    model the mount's nominal axis is aimed at the point (the Rochester guide's solution); with
    the ``camera`` input (the model at the current zoom, e.g. from CamCalib, its
    ``T_mount_camera`` relative to this unit's head) the point is brought to the principal point
    through the whole model, and re-aimed whenever a new model arrives (the zoom changed), so a
    watched point stays centred as the operator zooms in. Commands out of travel are refused
    and reported in ``state.status``. Publishes the angles and the camera mount's pose
    ``T_<world_frame>_<mount_name>`` every tick (give it a ``rate``). The unit's base is the
    static frame ``world_frame->ptu_frame`` (Z forward, Y down, X right, as the guide's FLANGE).
    """

    TYPE = "PTU"

    class Params(Parameters):
        world_frame: str = param("base", "frame of aim points and of the published pose")
        ptu_frame: str = param("ptu", "static frame of the unit's base (Z forward, Y down)")
        mount_name: str = param("ptu_mount", "name of the (moving) camera mount frame it publishes")
        initial_pan_deg: float = param(0.0, "pan at start", unit="deg", ge=-159, le=159)
        initial_tilt_deg: float = param(0.0, "tilt at start", unit="deg", ge=-47, le=31)
        max_rate: float = param(1.0, "slew rate limit per axis", unit="rad/s", gt=0, le=5)
        max_accel: float = param(4.0, "acceleration limit per axis", unit="rad/s^2", gt=0)

        def required_frames(self) -> list[tuple[str, str]]:
            """The unit's base in the world frame."""
            return [(self.world_frame, self.ptu_frame)]

    command = Input(PtuCommand, required=False, doc="angles or a point to aim at")
    camera = Input(
        CameraModel, required=False, doc="model of the carried camera at its zoom (aims with it)"
    )
    state = Output(PtuState, measured=True, doc="pan, tilt and their rates")
    mount_pose = Output(Pose, measured=True, doc="T_world_mount: the camera mount's pose")

    def start(self) -> None:
        p = self.params
        try:
            self.T_base_ptu = self.context.frames.lookup(p.world_frame, p.ptu_frame)
        except KeyError:
            raise UserError(
                f"PTU `{self.name}`: expected a static frame {p.world_frame}->{p.ptu_frame} "
                "(the unit's base) in the graph's frames, found none"
            ) from None
        self.geometry = PtuGeometry(max_rate=p.max_rate, max_accel=p.max_accel)
        self.unit = SimPtu(
            self.geometry, np.radians(p.initial_pan_deg), np.radians(p.initial_tilt_deg)
        )
        self._status = DEVICE_OK
        self._point: np.ndarray | None = None  # the point being watched (point mode)
        self._camera_seq = -1  # the camera model last aimed with
        self._last: float | None = None
        self._refused = 0

    def step(self, now: float) -> None:
        command = self.command.get(now)
        if command is not None and self.command.fresh:
            self._obey(command, now)
        elif self._point is not None and self.camera.fresh:
            model = self.camera.get(now)
            if model is not None and model.seq != self._camera_seq:
                self._aim(self._point, now)  # a new model (the zoom changed): re-aim
        dt = 0.0 if self._last is None else now - self._last
        self._last = now
        if dt > 0:
            self.unit.step(dt)
        pan, tilt = self.unit.angles
        self.state.send(
            PtuState(
                pan=float(pan),
                tilt=float(tilt),
                pan_rate=float(self.unit.rates[0]),
                tilt_rate=float(self.unit.rates[1]),
                moving=self.unit.moving,
                status=self._status,
            )
        )
        self.mount_pose.send(
            Pose(
                matrix=self.T_base_ptu @ self.geometry.T_ptu_mount(pan, tilt),
                parent=self.params.world_frame,
                child=self.params.mount_name,
            )
        )

    def _obey(self, command: PtuCommand, now: float) -> None:
        if command.mode == PtuMode.ANGLES:
            self._point = None
            try:
                self.unit.command(command.pan, command.tilt)
                self._status = DEVICE_OK
            except PtuLimitError as exc:
                self._refuse(str(exc))
        elif command.mode != PtuMode.POINT:  # a message made in this process, not decoded
            self._refuse(f"unknown PTU mode {command.mode!r}; expected one of {PtuMode.listed()}")
        elif command.frame != self.params.world_frame:
            self._refuse(
                f"aim point in frame `{command.frame}`, expected `{self.params.world_frame}`"
            )
        else:
            self._aim(np.asarray(command.point, dtype=float), now)

    def _aim(self, point: np.ndarray, now: float) -> None:
        model = self.camera.get(now)
        camera = None if model is None else pinhole_from_message(model)
        if model is not None:
            self._camera_seq = model.seq
        try:
            pan, tilt = aim_in_base(self.geometry, self.T_base_ptu, point, camera)
            if np.max(np.abs(np.array([pan, tilt]) - self.unit.targets)) > 1e-7:
                self.unit.command(pan, tilt)
        except PtuLimitError as exc:
            self._point = None
            self._refuse(str(exc))
            return
        self._point = point
        self._status = DEVICE_OK

    def _refuse(self, reason: str) -> None:
        self._refused += 1
        self._status = f"refused: {reason}"
        self.log.warning("PTU %s: %s", self.name, reason)

    def summary(self) -> dict[str, object]:
        pan, tilt = np.degrees(self.unit.angles)
        return {"pan_deg": float(pan), "tilt_deg": float(tilt), "refused": self._refused}
