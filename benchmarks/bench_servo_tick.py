"""Benchmark: one servo-side tick, REG_VEL -> ROTATE_KIN -> WOLVERINE_KIN -> WOLVERINE_JNTS (sim).

Rows, all measured in this run on the same machine:

* ``numpy floor``: the irreducible numpy work of a DLS tick: six chained 4x4 products (forward
  kinematics) and one 6x6 SVD. The baseline.
* ``pure functions``: the same tick as plain function calls (velocity register, twist transform,
  Jacobian + DLS, simulated joints), no messages or ports.
* ``modules``: the four modules wired port to port as the scheduler wires them (outputs feed
  input registers), one ``step`` each per tick, messages built and stamped.
* ``vsServo step`` (vision side, for reference): contour features, law and stage machine.

Run: ``python benchmarks/bench_servo_tick.py [--quick]``; writes benchmarks/results/servo_tick.json.
Goal: a module tick under 200 us.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.common import write_results  # noqa: E402
from umbra.connectors.messages import Contour, JointState, Twist  # noqa: E402
from umbra.connectors.module import ModuleContext  # noqa: E402
from umbra.modules.arm.dh import puma560  # noqa: E402
from umbra.modules.arm.dls import DLSSettings, solve_dls  # noqa: E402
from umbra.modules.arm.jacobian import jacobian_and_pose, tool_twist_in_base  # noqa: E402
from umbra.modules.arm.reg_vel import RegVel  # noqa: E402
from umbra.modules.arm.rotate_kin import RotateKin  # noqa: E402
from umbra.modules.arm.sim_joints import SimJoints  # noqa: E402
from umbra.modules.arm.velocity_register import VelocityRegister  # noqa: E402
from umbra.modules.arm.wolverine_jnts import WolverineJnts  # noqa: E402
from umbra.modules.arm.wolverine_kin import WolverineKin  # noqa: E402
from umbra.modules.geometry.transforms import (  # noqa: E402
    transform_from_xyz_rpy_deg,
    twist_tool_from_camera,
)
from umbra.modules.servo.vsservo import VsServo  # noqa: E402

GOAL_US = 200.0
DT = 0.002  # 500 Hz servo tick
Q0_DEG = [10.0, 50.0, -170.0, 5.0, 40.0, 15.0]
T_TOOL_CAMERA = transform_from_xyz_rpy_deg([0.0, 0.06, 0.04], [0.0, 0.0, 90.0])
CAMERA_TWIST = np.array([0.01, -0.005, 0.02, 0.0, 0.0, 0.05])


def time_per_call(fn: Callable[[], None], iterations: int, repeats: int) -> dict[str, float]:
    """Median and best of ``repeats`` runs of ``iterations`` calls, microseconds per call."""
    for _ in range(max(10, iterations // 20)):  # warm-up
        fn()
    samples = []
    for _ in range(repeats):
        start = time.perf_counter_ns()
        for _ in range(iterations):
            fn()
        samples.append((time.perf_counter_ns() - start) / iterations / 1000.0)
    return {"median_us": float(np.median(samples)), "best_us": float(np.min(samples))}


def numpy_floor() -> Callable[[], None]:
    rng = np.random.default_rng(0)
    links = rng.normal(size=(6, 4, 4))
    J = rng.normal(size=(6, 6))

    def tick() -> None:
        T = links[0]
        for i in range(1, 6):
            T = T @ links[i]
        np.linalg.svd(J)

    return tick


def pure_tick() -> Callable[[], None]:
    table = puma560()
    sim = SimJoints(table, np.radians(Q0_DEG))
    register = VelocityRegister()
    settings = DLSSettings()
    clock = {"now": 0.0}

    def tick() -> None:
        now = clock["now"] = clock["now"] + DT
        register.put(CAMERA_TWIST, now)
        out = register.output(now)
        tool_twist = twist_tool_from_camera(T_TOOL_CAMERA, out.twist)
        q = sim.q_reported
        J, T_base_tool = jacobian_and_pose(table, q)
        result = solve_dls(
            J,
            tool_twist_in_base(T_base_tool, tool_twist),
            q,
            table.q_min,
            table.q_max,
            table.qd_max,
            settings,
        )
        sim.step(result.rates, DT)

    return tick


class Chain:
    """The four servo-side modules wired output -> input register, as the scheduler does."""

    def __init__(self) -> None:
        self.now = 0.0
        context = ModuleContext()
        context.frames.add("tool", "camera", T_TOOL_CAMERA)
        clock = lambda: self.now  # noqa: E731

        def build(cls, params):
            module = cls(cls.__name__, cls.Params(**params), context)
            module.bind_ports(clock)
            return module

        self.reg = build(RegVel, {})
        self.rot = build(RotateKin, {})
        self.kin = build(WolverineKin, {})
        self.jnts = build(WolverineJnts, {"initial_q_deg": Q0_DEG})
        wires = [
            (self.reg, "twist", self.rot, "camera_twist"),
            (self.rot, "tool_twist", self.kin, "tool_twist"),
            (self.kin, "joint_rates", self.jnts, "rates"),
            (self.jnts, "joint_state", self.kin, "joint_state"),  # delayed in a graph
        ]
        for src, out, dst, inp in wires:
            src.outputs[out].sinks.append(dst.registers[inp].write)
        self.modules = (self.reg, self.rot, self.kin, self.jnts)
        for module in self.modules:
            module.start()
        self.command = self.reg.registers["command"]

    def tick(self) -> None:
        self.now += DT
        self.command.write(Twist(vector=CAMERA_TWIST, frame="camera", stamp=self.now), self.now)
        for module in self.modules:
            module.step(self.now)
            for register in module.registers.values():
                register.fresh = False

    def stop(self) -> None:
        for module in self.modules:
            module.stop()


def vsservo_step() -> Callable[[], None]:
    context = ModuleContext()
    state = {"now": 0.0}
    module = VsServo("servo", VsServo.Params(acquire_frames=1), context)
    module.bind_ports(lambda: state["now"])
    module.start()
    angles = np.linspace(0, 2 * np.pi, 64, endpoint=False)
    vertices = np.c_[360 + 80 * np.cos(angles), 250 + 50 * np.sin(angles)]
    contour = Contour(
        vertices=vertices, centroid=vertices.mean(0), area=0.0, orientation=0.0, axes=np.zeros(2)
    )
    register = module.registers["contour"]

    def tick() -> None:
        state["now"] += 0.02
        register.write(contour, state["now"])
        module.step(state["now"])
        register.fresh = False

    return tick


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer iterations (smoke run)")
    args = parser.parse_args(argv)
    iterations, repeats = (300, 3) if args.quick else (3000, 7)

    chain = Chain()
    rows = {
        "numpy floor (6x 4x4 matmul + 6x6 SVD)": time_per_call(numpy_floor(), iterations, repeats),
        "pure functions tick": time_per_call(pure_tick(), iterations, repeats),
        "modules tick (4 modules, ports)": time_per_call(chain.tick, iterations, repeats),
        "vsServo step (vision side)": time_per_call(vsservo_step(), iterations, repeats),
    }
    chain.stop()
    state = chain.jnts.outputs["joint_state"].last
    assert isinstance(state, JointState) and np.all(np.isfinite(state.position))

    floor = rows["numpy floor (6x 4x4 matmul + 6x6 SVD)"]["median_us"]
    pure = rows["pure functions tick"]["median_us"]
    print(
        f"servo tick benchmark ({'quick' if args.quick else 'full'}: "
        f"{repeats} x {iterations} calls; median per call)"
    )
    print(f"{'what':42s} {'median us':>10s} {'best us':>9s} {'x floor':>8s} {'x pure':>7s}")
    for name, row in rows.items():
        row["ratio_to_floor"] = row["median_us"] / floor
        row["ratio_to_pure"] = row["median_us"] / pure
        print(
            f"{name:42s} {row['median_us']:10.1f} {row['best_us']:9.1f} "
            f"{row['ratio_to_floor']:8.2f} {row['ratio_to_pure']:7.2f}"
        )
    module_us = rows["modules tick (4 modules, ports)"]["median_us"]
    verdict = "meets" if module_us < GOAL_US else "MISSES"
    print(f"module tick {module_us:.1f} us {verdict} the {GOAL_US:.0f} us goal")

    result = {
        "iterations": iterations,
        "repeats": repeats,
        "goal_us": GOAL_US,
        "meets_goal": module_us < GOAL_US,
        "numpy": np.__version__,
        "rows": rows,
    }
    out = write_results("servo_tick", result, quick=args.quick)
    print(f"wrote {out.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
