"""The simulated ROS 2 robot as a ROS 2 node, through ``zenoh-ros2-sdk`` only (its own
publishers, subscribers, CDR and RIHS01 hashes: nothing of umbra's ROS 2 code).

Topics (node ``sim_robot``):

====================================  ================================  ==========================
``/joint_states``                     sensor_msgs/msg/JointState        out, 100 Hz: j1..j6 [rad]
                                                                        as the encoders report
                                                                        them, and ``gripper``
                                                                        (0 closed .. 1 open)
``/wrist_camera/image_raw``           sensor_msgs/msg/Image             out, ``bgr8`` 1280x720,
                                                                        ``header.stamp`` the
                                                                        capture's wall-clock time
``/wrist_camera/patch_truth``         geometry_msgs/msg/PolygonStamped  out, the patch's true
                                                                        outline in that frame
                                                                        [px], same stamp (a
                                                                        simulator's ground truth)
``/forward_velocity_controller/       std_msgs/msg/Float64MultiArray    in: joint velocities
commands``                                                              [rad/s], j1..j6, as
                                                                        ros2_control's forward
                                                                        velocity controller
``/gripper/command``                  std_msgs/msg/String               in: ``open`` or ``close``
====================================  ================================  ==========================

A velocity command is obeyed for ``--watchdog`` seconds at most (the drive's own watchdog): a
controller that goes silent leaves the arm at rest. When the gripper has closed the robot judges
the grasp against the truth and writes its verdict (JSON) to ``--verdict``; it ends after
``--linger`` seconds more, at ``--duration``, or on SIGINT/SIGTERM.

Run: ``python -m examples.ros2_robot --router tcp/127.0.0.1:7447 --verdict verdict.json``.
"""

from __future__ import annotations

import argparse
import json
import signal
import tempfile
import threading
import time
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from examples.ros2_robot.plant import RobotPlant, RobotSetup
from examples.ros2_robot.sdk_session import open_sdk

NODE = "sim_robot"
#: The gripper's joint in ``/joint_states``.
GRIPPER_JOINT = "gripper"
COMMAND_TOPIC = "/forward_velocity_controller/commands"


class SimRobotNode:
    """The robot's ROS 2 node: publishers, subscriptions, and the loops that drive them."""

    def __init__(self, sdk: Any, port: int, plant: RobotPlant, domain: int = 0) -> None:
        self.plant = plant
        kw = {"node_name": NODE, "domain_id": domain, "router_port": port}
        self._joints = sdk.ROS2Publisher("/joint_states", "sensor_msgs/msg/JointState", **kw)
        self._image = sdk.ROS2Publisher("/wrist_camera/image_raw", "sensor_msgs/msg/Image", **kw)
        self._truth = sdk.ROS2Publisher(
            "/wrist_camera/patch_truth", "geometry_msgs/msg/PolygonStamped", **kw
        )
        self._types = self._joints.session_mgr.store.types
        self.refused: dict[str, str] = {}
        self._subs = [
            sdk.ROS2Subscriber(
                COMMAND_TOPIC, "std_msgs/msg/Float64MultiArray", self._on_rates, **kw
            ),
            sdk.ROS2Subscriber("/gripper/command", "std_msgs/msg/String", self._on_gripper, **kw),
        ]
        self.sent = {"joint_states": 0, "images": 0}
        self.stop = threading.Event()

    # -- in --------------------------------------------------------------------------------------
    def _on_rates(self, msg: Any) -> None:
        rates = np.asarray(msg.data, dtype=np.float64)
        n = len(self.plant.joint_names)
        if rates.shape != (n,) or not np.all(np.isfinite(rates)):
            self.refused["rates"] = f"expected {n} finite joint velocities, found {rates.tolist()}"
            return
        self.plant.command_rates(rates, time.monotonic())

    def _on_gripper(self, msg: Any) -> None:
        try:
            self.plant.command_gripper(str(msg.data), time.monotonic())
        except ValueError as exc:
            self.refused["gripper"] = str(exc)

    # -- out -------------------------------------------------------------------------------------
    def _header(self, stamp_ns: int, frame_id: str) -> Any:
        t = self._types
        stamp = t["builtin_interfaces/msg/Time"](sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9)
        return t["std_msgs/msg/Header"](stamp=stamp, frame_id=frame_id)

    def publish_joints(self) -> None:
        q, qd, gripper = self.plant.joint_state()
        self._joints.publish(
            header=self._header(time.time_ns(), "base"),
            name=[*self.plant.joint_names, GRIPPER_JOINT],
            position=np.append(q, gripper),
            velocity=np.append(qd, 0.0),
            effort=np.zeros(0),
        )
        self.sent["joint_states"] += 1

    def publish_frame(self) -> None:
        stamp_ns = time.time_ns()  # the capture: the frame shows the arm as it is now
        frame = self.plant.capture()
        h, w = frame.pixels.shape[:2]
        header = self._header(stamp_ns, "camera")
        self._image.publish(
            header=header,
            height=h,
            width=w,
            encoding="bgr8",
            is_bigendian=0,
            step=3 * w,
            data=frame.pixels.reshape(-1),
        )
        point = self._types["geometry_msgs/msg/Point32"]
        polygon = self._types["geometry_msgs/msg/Polygon"](
            points=[point(x=float(u), y=float(v), z=0.0) for u, v in frame.outline]
        )
        self._truth.publish(header=header, polygon=polygon)
        self.sent["images"] += 1

    # -- loops -----------------------------------------------------------------------------------
    def run_camera(self, rate_hz: float) -> None:
        """Frames at ``rate_hz`` until stopped (a frame late by its rendering skips, never
        bunches)."""
        period = 1.0 / rate_hz
        due = time.monotonic()
        while not self.stop.is_set():
            self.publish_frame()
            due = max(due + period, time.monotonic())
            self.stop.wait(max(0.0, due - time.monotonic()))

    def run(self, args: argparse.Namespace) -> dict[str, Any]:
        """Joints at ``args.rate`` Hz and the camera on its thread until the end; the record."""
        camera = threading.Thread(target=self.run_camera, args=(args.camera_rate,), daemon=True)
        camera.start()
        start = due = time.monotonic()
        judged_at: float | None = None
        period = 1.0 / args.rate
        while not self.stop.is_set():
            now = time.monotonic()
            self.plant.advance(now)
            self.publish_joints()
            if judged_at is None and self.plant.verdict.judged:
                judged_at = now
                write_json(args.verdict, self.record(now - start))
            if now - start > args.duration or (
                judged_at is not None and now - judged_at > args.linger
            ):
                break
            due = max(due + period, time.monotonic())
            self.stop.wait(max(0.0, due - time.monotonic()))
        self.stop.set()
        camera.join(timeout=5.0)
        record = self.record(time.monotonic() - start)
        write_json(args.verdict, record)
        return record

    def record(self, elapsed_s: float) -> dict[str, Any]:
        v = self.plant.verdict
        return {
            **{k: val for k, val in asdict(v).items() if k != "extra"},
            **v.extra,
            "elapsed_s": round(elapsed_s, 3),
            "velocity_commands": self.plant.commands,
            "watchdog_stops": self.plant.watchdog_stops,
            "sent": dict(self.sent),
            "refused": dict(self.refused),
        }

    def close(self) -> None:
        for entity in (*self._subs, self._joints, self._image, self._truth):
            entity.close()


def write_json(path: Path | None, data: dict[str, Any]) -> None:
    """``data`` to ``path`` at once (written aside, then renamed: a reader never sees half)."""
    if path is None:
        return
    with tempfile.NamedTemporaryFile("w", dir=path.parent, delete=False, suffix=".tmp") as f:
        json.dump(data, f, indent=2)
    Path(f.name).replace(path)


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="python -m examples.ros2_robot", description=__doc__)
    parser.add_argument("--router", default="tcp/127.0.0.1:7447", help="the ROS 2 zenoh router")
    parser.add_argument("--domain", type=int, default=0, help="ROS 2 domain id")
    parser.add_argument("--verdict", type=Path, help="write the grasp's verdict (JSON) here")
    parser.add_argument("--rate", type=float, default=100.0, help="joint states [Hz]")
    parser.add_argument("--camera-rate", type=float, default=30.0, help="camera frames [Hz]")
    parser.add_argument("--watchdog", type=float, default=0.1, help="drive watchdog [s]")
    parser.add_argument("--duration", type=float, default=300.0, help="end after [s]")
    parser.add_argument("--linger", type=float, default=2.0, help="run on after the grasp [s]")
    parser.add_argument("--seed", type=int, default=1, help="the camera noise's seed")
    parser.add_argument(
        "--msgs", type=Path, help="folder for the .msg files (default: a temporary one)"
    )
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        sdk, port = open_sdk(args.router, args.msgs or Path(tmp))
        plant = RobotPlant(RobotSetup(watchdog_s=args.watchdog), seed=args.seed)
        node = SimRobotNode(sdk, port, plant, args.domain)
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, lambda *_: node.stop.set())
        print(f"{NODE}: on {args.router}, domain {args.domain}", flush=True)
        try:
            record = node.run(args)
        finally:
            node.close()
    print(f"{NODE}: {record['verdict']}", flush=True)
    return 0
