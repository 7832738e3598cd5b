"""DigiCam: camera frames from OpenCV capture or from the simulated wrist camera."""

from __future__ import annotations

from collections import Counter
from typing import TYPE_CHECKING, Literal

import numpy as np
from pydantic import model_validator

from umbra.connectors import (
    Input,
    Module,
    Output,
    Parameters,
    ParamProblem,
    UserError,
    from_param,
    param,
)
from umbra.connectors.limits import MAX_IMAGE_SIDE_PX
from umbra.connectors.messages import CameraModel, Contour, Image, Pose, Poses
from umbra.connectors.params import Channel, NonNegative, Positive
from umbra.modules.vision.capture_source import CameraSource, CaptureError, CaptureSource
from umbra.modules.vision.digicam_sim import SimCameraSide

if TYPE_CHECKING:  # imported by start(): checking a graph needs no OpenCV
    from umbra.modules.vision.capture import CaptureReader


class DigiCam(Module["DigiCam.Params"]):
    """Frames from a camera device, a video file, a stream URL, or the simulated wrist camera.

    ``source``: ``sim``, a device index (``0``, quoted or not) or device path (``/dev/video0``), a
    video file, an image sequence (``imgs/img_%04d.png``), a single image (``.png``, ``.jpg``...),
    or a stream URL (``rtsp://``, ``http://``). A device or stream is read in its own thread and
    each step sends the newest frame once; a video file or image sequence plays one frame per
    step, in order (set the module's rate to the file's frame rate for real-time playback; on the
    sim clock the step waits for the decoder, which costs no simulated time, but never again
    after a wait in vain), and at its end loops, holds its last frame, or stops the run
    (``at_end``); a single image is sent again at every step. A source that cannot be opened is
    an error at start that names the cause (not found, refused, timed out, cannot decode). A
    source that stops delivering for ``stale_after`` seconds is reported once, and its last
    frame is sent again marked ``stale``; the run goes on and recovers when frames come back.

    ``sim`` renders the scene (table, tray, tool, colored patch) through the camera model of the
    ``camera_model`` input (else the intrinsics parameters) from the camera pose of the
    ``camera_pose`` input (else straight down from ``camera_height_m`` above the patch). The
    pose input may be the camera's pose in the world, or a mount's pose (``tool`` in ``base``):
    it is completed with the camera model's mount transform or the graph's static frames. The
    ``truth`` output carries the patch outline in the image (ground truth, sim only).

    Scheduled faults (``sim``, for failure-injection trials): ``fault`` begins ``fault_at_s``
    seconds of the module's clock after its first step, and lasts ``fault_duration_s`` (0: to the
    end of the run; an occluder withdrawn, say, so an operator can re-seed and resume).
    ``occluder``: a flat slab of ``fault_rgb`` (skin by default), 2 mm above the patch, slides
    over it from its ``fault_side`` at ``fault_speed_mps``, starting 5 mm outside it, and stays
    once it covers it (at the default 0.05 m/s half of a 4 cm side is covered 0.5 s after the
    fault began). ``remove_patch``: the patch is gone, the tool stays. ``distractor``: a second
    patch of the same color and size lies against the patch side ``fault_side``. ``freeze``: a
    frozen frame grabber: no new rendering, the last frame before the fault is sent again on
    every step with new stamps (marked ``stale`` only with ``fault_frozen_stale``; with
    ``fault_at_s`` 0 the first frame is the one held). ``lag``: a vision side that fell behind:
    frames show the scene in slow motion (``LAG_PLAYBACK`` of real speed) until they are
    ``fault_lag_s`` behind, each carrying its capture time (its origin), as frames a starved
    process takes from a queue would. The ``truth`` output
    keeps following the world during a freeze (the true outline, computed without rendering).
    Being driven by the parameters and the clock only, a fault plays the same in one process or
    split over many.
    ``summary()`` reports ``fault`` and ``fault_started_at``, the clock time [s] of the first
    frame showing the fault (None before).
    """

    TYPE = "DigiCam"

    class Params(Parameters):
        source: CameraSource = param(
            "sim", "`sim`, a device index or path, a video file, an image sequence or image, a URL"
        )
        width: int = param(
            0, "frame width; 0: the source's (sim: 640)", unit="px", ge=0, le=MAX_IMAGE_SIDE_PX
        )
        height: int = param(
            0, "frame height; 0: the source's (sim: 480)", unit="px", ge=0, le=MAX_IMAGE_SIDE_PX
        )
        fps: float = param(0.0, "frame rate asked of a device; 0: its own", unit="Hz", ge=0)
        at_end: Literal["loop", "hold", "stop"] = param("loop", "what a video file does at its end")
        stale_after: float = param(1.0, "no new frame this long marks output stale", unit="s", gt=0)
        open_timeout: float = param(5.0, "how long a stream may take to open", unit="s", gt=0)
        camera_frame: str = param("camera", "frame name of the images")
        world_frame: str = param("world", "frame of the simulated scene (sim)")
        fx: float = param(600.0, "focal length in x without a camera_model (sim)", unit="px", gt=0)
        fy: float = param(600.0, "focal length in y without a camera_model (sim)", unit="px", gt=0)
        skew: float = param(0.0, "skew without a camera_model (sim)", unit="px")
        u0: float = param(320.0, "principal point u without a camera_model (sim)", unit="px")
        v0: float = param(240.0, "principal point v without a camera_model (sim)", unit="px")
        dist: list[float] = param(
            [0.0, 0.0, 0.0, 0.0, 0.0], "k1 k2 p1 p2 k3 (sim)", min_length=4, max_length=5
        )
        camera_height_m: float = param(
            0.22, "camera above the patch without a pose input (sim)", unit="m", gt=0
        )
        patch_xyz_m: list[float] = param(
            [0.0, 0.0, 0.03], "patch centre in the world (sim)", min_length=3, max_length=3
        )
        patch_yaw_deg: float = param(0.0, "patch yaw about world z (sim)", unit="deg")
        patch_size_m: list[Positive] = param(
            [0.06, 0.04], "patch sides x, y (sim)", unit="m", min_length=2, max_length=2
        )
        patch_rgb: list[Channel] = param(
            [30, 170, 60], "patch color, RGB 0..255 (sim)", min_length=3, max_length=3
        )
        patch_present: bool = param(True, "whether the patch is there (sim)")
        background: Literal["flat", "photo"] = param("flat", "table: flat color or a photo (sim)")
        gain: float = param(1.0, "lighting gain (sim)", ge=0)
        cast_rgb: list[NonNegative] = param(
            [1.0, 1.0, 1.0], "per-channel lighting gains R G B (sim)", min_length=3, max_length=3
        )
        noise_sigma: float = param(0.0, "sensor noise (sim)", unit="gray levels", ge=0)
        blur_length_px: float = param(0.0, "motion blur length (sim)", unit="px", ge=0)
        blur_angle_deg: float = param(0.0, "motion blur direction from u (sim)", unit="deg")
        fault: Literal["none", "occluder", "remove_patch", "distractor", "freeze", "lag"] = param(
            "none", "scheduled fault: none, occluder, remove_patch, distractor, freeze, lag (sim)"
        )
        fault_lag_s: float = param(
            2.0,
            "lag: frames fall this far behind the scene, stamped when captured (sim)",
            unit="s",
            gt=0,
            le=60,
        )
        fault_at_s: float = param(
            3.0, "fault begins this long after the camera's first step (sim)", unit="s", ge=0
        )
        fault_duration_s: float = param(
            0.0, "the fault ends this long after it began; 0: never (sim)", unit="s", ge=0
        )
        fault_speed_mps: float = param(
            0.05, "occluder speed over the patch, in the patch plane (sim)", unit="m/s", gt=0
        )
        fault_side: Literal["+x", "-x", "+y", "-y"] = param(
            "+y", "patch side the occluder comes from, or the distractor touches (sim)"
        )
        fault_rgb: list[Channel] = param(
            [225, 180, 150], "occluder color, RGB 0..255 (sim)", min_length=3, max_length=3
        )
        fault_frozen_stale: bool = param(
            False, "freeze: mark the re-sent frames stale (a grabber that says so) (sim)"
        )

        @model_validator(mode="after")
        def _size_and_fault(self) -> DigiCam.Params:
            """A frame size is whole (both sides or neither); a fault is simulated."""
            if (self.width == 0) != (self.height == 0):
                raise ParamProblem(
                    "width" if self.width == 0 else "height",
                    f"is needed too: give both width and height, or neither (0), found "
                    f"width {self.width} and height {self.height}",
                )
            if self.fault != "none" and str(self.source).strip() != "sim":
                raise ParamProblem(
                    "fault", f"{self.fault!r} needs source `sim`, found source {self.source!r}"
                )
            return self

    # sim: a wired pose or model is waited for before the first frame (no frame from a pose
    # nobody measured); unwired, the parameters stand in for it
    camera_pose = Input(
        Pose, required=False, feedback=True, doc="camera (or its mount) pose, for sim"
    )
    camera_model = Input(CameraModel, required=False, feedback=True, doc="intrinsics, for sim")
    patch_pose = Input(Pose, required=False, feedback=True, doc="T_world_patch, for sim")
    arm_poses = Input(
        Poses,
        required=False,
        feedback=True,
        doc="the arm's TRUE frames (World.arm_poses), for sim: the arm drawn over the scene",
    )
    image = Output(
        Image,
        frame=from_param("camera_frame"),
        # a capture is new data; a sim frame shows the world as its poses had it
        origin_from=("camera_pose", "patch_pose", "arm_poses"),
        doc="BGR frames",
    )
    truth = Output(
        Contour, measured=True, doc="sim only: the patch outline in the image (ground truth)"
    )
    camera_info = Output(
        CameraModel,
        doc="sim only: the intrinsics each frame is rendered with (the camera_model input's, "
        "else the parameters'), sent with each frame when wired or mapped to ROS 2 "
        "(its camera_info)",
    )

    # -- lifecycle ------------------------------------------------------------------------------

    def start(self) -> None:
        p = self.params
        self._reader: CaptureReader | None = None
        self._sim: SimCameraSide | None = None  #: the simulated camera (source: sim)
        self._last: Image | None = None
        self._last_new_at = -np.inf
        self._stale = False
        self._stale_events = 0
        self._sent = 0
        self._ended_reported = False
        self._last_number: int | None = None
        #: live frames by where their capture time came from: driver, grab, step (sim clock)
        self._stamped_by: Counter[str] = Counter()
        self._decoder_stalled = False
        size = (p.width, p.height) if p.width and p.height else None
        if str(p.source).strip() == "sim":
            self._sim = SimCameraSide(self)
            return
        from umbra.modules.vision.capture import CaptureReader

        source = CaptureSource.parse(p.source)
        try:
            self._reader = CaptureReader(
                source, size, p.fps, loop=p.at_end == "loop", open_timeout_s=p.open_timeout
            )
        except CaptureError as exc:
            raise UserError(f"{self.name}: {exc} (parameter source: {p.source!r})") from None
        self._reader.start()

    def stop(self) -> None:
        reader: CaptureReader | None = getattr(self, "_reader", None)
        if reader is not None:
            reader.close()

    def summary(self) -> dict[str, object]:
        out: dict[str, object] = {"frames": self._sent, "stale_events": self._stale_events}
        if self._stamped_by:
            out["capture_stamps"] = dict(self._stamped_by)
        if self._sim is not None:
            out["renderers_built"] = self._sim.sim.renderers_built
            out["fault"] = self.params.fault
            out["fault_started_at"] = self._sim.fault_started_at
        return out

    # -- behaviour ------------------------------------------------------------------------------

    def step(self, now: float) -> None:
        if self._sim is not None:
            self._sim.step(now)
        else:
            self._step_capture(now)

    def _send(
        self, pixels: np.ndarray, now: float, stamp: float | None = None, origin: float = 0.0
    ) -> None:
        """Send a new frame captured at ``stamp`` [s] (``now`` unless told), made from sensor
        data as old as ``origin`` [s] (0: its capture, a new origin)."""
        captured = now if stamp is None else stamp
        self._last = Image(
            pixels=pixels,
            frame=self.params.camera_frame,
            stamp=captured,
            origin=origin or captured,
        )
        self.image.send(self._last)
        self._sent += 1
        self._last_new_at = now
        if self._stale:
            self._stale = False
            self.log.info("%s: frames are coming again", self.name)

    def _step_capture(self, now: float) -> None:
        reader = self._reader
        assert reader is not None
        if reader.still is not None:
            self._send(reader.still, now)  # a still image: the same frame at the module's rate
            return
        if reader.is_file:
            # On the sim clock a step waits for the decoder (no simulated time passes), but a
            # decoder that kept it waiting in vain is not waited for again until it delivers.
            waits = self.context.clock == "sim" and not reader.ended.is_set()
            wait = 1.0 if waits and not self._decoder_stalled else 0.0
            frame = reader.next_frame(timeout_s=wait)
            self._decoder_stalled = frame is None and wait > 0
            if frame is not None:
                self._send(frame, now)
                return
            if reader.drained() and not self._ended_reported:
                self._ended_reported = True
                what = reader.source.describe()
                if self.params.at_end == "stop":
                    self.context.request_stop(f"{self.name}: {what} ended", 0)
                    return
                if reader.loop_failed:
                    self.log.warning("%s: %s cannot be read again from its start", self.name, what)
                self.log.info("%s: %s ended; holding its last frame", self.name, what)
        else:
            latest = reader.latest()
            if latest is not None and latest.number != self._last_number:
                self._last_number = latest.number
                # on the real clock a live frame is as old as its capture (the driver's stamp
                # where the device gives one), not as the step that takes it over
                real = self.context.clock == "real"
                self._stamped_by[latest.stamped_by if real else "step"] += 1
                self._send(latest.pixels, now, stamp=latest.captured_at if real else None)
                return
        self._check_stale(now)

    def _check_stale(self, now: float) -> None:
        if self._stale or self._last is None:
            return
        if now - self._last_new_at >= self.params.stale_after:
            self._stale = True
            self._stale_events += 1
            self.log.warning(
                "%s: no new frame for %.2f s from %s; marking its output stale",
                self.name,
                now - self._last_new_at,
                self.params.source,
            )
            self.image.send(
                Image(pixels=self._last.pixels, frame=self._last.frame, stale=True, stamp=now)
            )
