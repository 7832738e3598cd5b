"""Benchmark: ROS 2 on the wire beside umbra's own links, and what ``--ros2`` costs the servo.

1. **Delivery.** One run of a two-process graph (``umbra run --ros2``): process ``a`` sends a
   ``JointState`` at 100 Hz and a 1280x720 BGR image at 30 Hz, both to a sink module in process
   ``b`` over umbra's links (zenoh, loopback) *and*, through the graph's ``ros2:`` section, to
   ROS 2 as ``/joint_states`` and ``/wrist_camera/image_raw``, where a ``zenoh-ros2-sdk``
   subscriber (a zenoh client of a router on loopback, in this process) takes them. Latency is
   the sample's age when it is in the consumer's hands: for umbra's link the sink's tick time
   minus the sample's origin (one host: both processes on ``CLOCK_MONOTONIC``), for ROS 2 the
   wall clock at the sdk's callback (CDR decoded) minus ``header.stamp`` (the origin on the wall
   clock, related within a microsecond). Rate: samples taken per second over the window.
2. **Servo tick lateness** with and without ``--ros2``: the simulated arm's servo side
   (``common.SIM_ARM_SMART``: REG_VEL -> ROTATE_KIN -> WOLVERINE_KIN -> WOLVERINE_JNTS at
   100 Hz) whose joint states and link poses the ``ros2:`` section maps to ``/joint_states``
   and ``/tf``; the process's tick lateness p50/p99/max (its ``summary.json``), runs alternated
   pass after pass. Goal: unchanged within noise.

Run: ``python benchmarks/bench_ros2.py [--quick]``; writes benchmarks/results/ros2.json.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(REPO))

from benchmarks.common import (  # noqa: E402
    SIM_ARM_SMART,
    SIM_ARM_SMART_WIRES,
    percentiles,
    plugin_env,
    table,
    write_results,
)
from examples.ros2_robot.sdk_session import open_sdk  # noqa: E402
from umbra.connectors import Input, Module, Output, Parameters, param  # noqa: E402
from umbra.connectors.messages import Image, JointState  # noqa: E402
from umbra.runtime.links.config import free_loopback_ports  # noqa: E402
from umbra.runtime.ros2.router import open_router  # noqa: E402

IMAGE_SHAPE = (720, 1280, 3)
JOINTS = ("j1", "j2", "j3", "j4", "j5", "j6")


# -- umbra modules (registered in the child processes through an entry point) --------------------
class R2Joints(Module[Parameters]):
    """Sends a joint state each step, dated now."""

    joint_state = Output(JointState, doc="six joints")

    def step(self, now: float) -> None:
        q = np.full(6, 0.1 * np.sin(now))
        self.joint_state.send(JointState(names=JOINTS, position=q, stamp=now, origin=now))


class R2Camera(Module[Parameters]):
    """Sends a 1280x720 BGR image each step, dated now (a new picture each time)."""

    image = Output(Image, doc="frames")

    def start(self) -> None:
        self._pixels = np.random.default_rng(1).integers(0, 256, IMAGE_SHAPE, dtype=np.uint8)

    def step(self, now: float) -> None:
        self._pixels[0, 0, 0] += 1
        self.image.send(Image(pixels=self._pixels, frame="camera", stamp=now, origin=now))


class R2Sink(Module["R2Sink.Params"]):
    """Records the tick time [s] and the age [s] of each sample when it steps on it (its tick
    time minus its origin)."""

    class Params(Parameters):
        result: str = param("sink.json", "result file in the output folder")

    joint_state = Input(JointState, trigger=True, doc="from R2Joints")
    image = Input(Image, trigger=True, doc="from R2Camera")

    def start(self) -> None:
        self._ages: dict[str, list[tuple[float, float]]] = {"joint_state": [], "image": []}

    def step(self, now: float) -> None:
        for name in self._ages:
            reg = getattr(self, name)
            if reg.fresh and reg.value is not None:
                self._ages[name].append((now, now - reg.value.origin))

    def stop(self) -> None:
        (self.context.output_dir / self.params.result).write_text(json.dumps(self._ages))


ENTRY_POINTS = {n: f"bench_ros2:{n}" for n in ("R2Joints", "R2Camera", "R2Sink")}

DELIVERY_GRAPH = """
graph: bench_ros2
clock: real
processes: {a: {}, b: {}}
modules:
  joints: {type: R2Joints, process: a, rate: 100}
  camera: {type: R2Camera, process: a, rate: 30}
  sink: {type: R2Sink, process: b}
connections:
  - joints.joint_state -> sink.joint_state
  - camera.image -> sink.image
ros2:
  out:
    joints.joint_state: {topic: /joint_states, type: sensor_msgs/msg/JointState}
    camera.image: {topic: /wrist_camera/image_raw, type: sensor_msgs/msg/Image}
"""

SERVO_GRAPH = f"""
graph: bench_ros2_servo
clock: real
processes: {{smart: {{realtime_priority: 50}}}}
frames:
  flange->tool: {{xyz: [0, 0, 0.14]}}
  tool->camera: {{xyz: [0, 0, -0.12]}}
modules:
{SIM_ARM_SMART}
connections:
{SIM_ARM_SMART_WIRES}
ros2:
  out:
    joints.joint_state: {{topic: /joint_states, type: sensor_msgs/msg/JointState}}
    kinematics.link_poses: {{topic: /tf, type: tf2_msgs/msg/TFMessage}}
"""


def _plugin_env(tmp: Path) -> dict[str, str]:
    """The environment of ``umbra run`` with this file's modules registered (an entry point)."""
    return plugin_env(tmp, "bench-ros2", ENTRY_POINTS)


def _run(tmp: Path, graph: str, name: str, seconds: float, *extra: str) -> Path:
    """``umbra run`` of ``graph`` for ``seconds``; its output folder (RuntimeError on failure)."""
    path = tmp / f"{name}.yaml"
    path.write_text(graph)
    out = tmp / name
    cmd = [sys.executable, "-m", "umbra.runtime.cli.main", "run", str(path), "--out", str(out)]
    done = subprocess.run(
        [*cmd, "--quiet", "--duration", str(seconds), *extra],
        env=_plugin_env(tmp),
        capture_output=True,
        text=True,
        timeout=600,
    )
    if done.returncode != 0:
        raise RuntimeError(f"umbra run {name} failed ({done.returncode}):\n{done.stderr[-3000:]}")
    return out


class _Taker:
    """An sdk subscription's callback: the wall-clock age [s] of each message's stamp on
    arrival, and the arrival times [s] (monotonic)."""

    def __init__(self) -> None:
        self.ages: list[float] = []
        self.times: list[float] = []
        self._lock = threading.Lock()

    def __call__(self, msg: Any) -> None:
        now_ns = time.time_ns()
        stamp_ns = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
        with self._lock:
            self.ages.append((now_ns - stamp_ns) / 1e9)
            self.times.append(time.monotonic())


def _rate(times: list[float]) -> float:
    """Samples per second between the first and the last."""
    return (len(times) - 1) / (times[-1] - times[0]) if len(times) > 1 else 0.0


def delivery(tmp: Path, seconds: float) -> dict[str, dict[str, Any]]:
    """Latency [ms] and rate [Hz] of joint states and images, umbra's link and ROS 2, one run."""
    endpoint = f"tcp/127.0.0.1:{free_loopback_ports(1)[0]}"
    router = open_router(endpoint)
    try:
        sdk, port = open_sdk(endpoint, tmp / "msgs")
        takers = {"joint_state": _Taker(), "image": _Taker()}
        subs = [
            sdk.ROS2Subscriber(topic, ros_type, takers[name], router_port=port)
            for name, topic, ros_type in (
                ("joint_state", "/joint_states", "sensor_msgs/msg/JointState"),
                ("image", "/wrist_camera/image_raw", "sensor_msgs/msg/Image"),
            )
        ]
        try:
            out = _run(tmp, DELIVERY_GRAPH, "delivery", seconds, "--ros2-router", endpoint)
        finally:
            for sub in subs:
                sub.close()
    finally:
        router.close()
    sink = json.loads((out / "sink.json").read_text())
    rows: dict[str, dict[str, Any]] = {}
    for name in ("joint_state", "image"):
        times, ages = (list(column) for column in zip(*sink[name], strict=True))
        rows[f"{name} umbra link"] = {
            **percentiles(np.asarray(ages) * 1e3, (50, 99)),
            "rate_hz": _rate(times),
            "samples": len(ages),
        }
        taker = takers[name]
        rows[f"{name} ROS 2 (sdk)"] = {
            **percentiles(np.asarray(taker.ages) * 1e3, (50, 99)),
            "rate_hz": _rate(taker.times),
            "samples": len(taker.ages),
        }
    return rows


def servo_lateness(tmp: Path, seconds: float, passes: int) -> dict[str, Any]:
    """The servo process's tick lateness [ms] with and without ``--ros2``, alternated."""
    endpoint = f"tcp/127.0.0.1:{free_loopback_ports(1)[0]}"
    router = open_router(endpoint)
    found: dict[str, list[dict[str, float]]] = {"without": [], "with --ros2": []}
    try:
        for p in range(passes):
            order = ["without", "with --ros2"] if p % 2 == 0 else ["with --ros2", "without"]
            for kind in order:
                extra = ["--ros2-router", endpoint] if kind != "without" else []
                out = _run(tmp, SERVO_GRAPH, f"servo_{p}_{kind[:4]}", seconds, *extra)
                s = json.loads((out / "summary.json").read_text())
                found[kind].append({k: float(s[f"lateness_{k}_ms"]) for k in ("p50", "p99", "max")})
    finally:
        router.close()
    return {
        kind: {
            **{k: float(np.median([r[k] for r in runs])) for k in ("p50", "p99", "max")},
            "runs": runs,
        }
        for kind, runs in found.items()
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="short runs (a smoke run)")
    args = parser.parse_args()
    seconds, servo_s, passes = (6.0, 6.0, 1) if args.quick else (20.0, 15.0, 3)
    with tempfile.TemporaryDirectory() as tmp:
        rows = delivery(Path(tmp), seconds)
        servo = servo_lateness(Path(tmp), servo_s, passes)
    print(f"Delivery to the consumer, one run of {seconds:g} s (latency ms; rate Hz)")
    print(
        table(
            [
                [name, r["p50"], r["p99"], r["max"], r["rate_hz"], r["samples"]]
                for name, r in rows.items()
            ],
            ["path", "p50 ms", "p99 ms", "max ms", "rate Hz", "samples"],
        )
    )
    print(f"\nServo tick lateness, {passes} pass(es) of {servo_s:g} s each (median of passes)")
    print(
        table(
            [[kind, r["p50"], r["p99"], r["max"]] for kind, r in servo.items()],
            ["servo process", "p50 ms", "p99 ms", "max ms"],
        )
    )
    path = write_results(
        "ros2",
        {"delivery": rows, "servo_lateness": servo, "seconds": seconds, "passes": passes},
        quick=args.quick,
    )
    print(f"\nwritten to {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
