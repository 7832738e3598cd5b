"""Links between processes: round-trip time and image throughput, against baselines run here.

Round trip (ping-pong between two processes) for a 48-byte twist (6 float64) and a 640x480x3
uint8 image, p50 and p99:

* umbra     — two modules in two processes of one graph, run by ``umbra run`` (zenoh links:
              scheduler wake-up and codec on both sides; the twist reliable/BLOCK, the image
              best-effort, written once into the producer's frame pool and read in place);
* noauth    — umbra as above with ``--insecure``: the links' identity checks and size bounds
              on, no per-run credentials or access rules;
* open      — umbra with ``--insecure --unchecked-links``: none of them (the links before they
              checked anything); paired, ``umbra ÷ open`` is what trust costs on a round trip
              and ``noauth ÷ open`` the share of the checks in the receiving callbacks;
* zenoh     — raw zenoh-python with the same payloads and the same configuration (peer, loopback,
              scouting off, shared memory on, same congestion control): ping puts and waits on a
              channel, pong republishes from its callback;
* codec     — twist only, a diagnostic: raw zenoh as above, but each side decodes the sample
              into a ``Twist`` with umbra's codec and encodes the next one (what a module's
              hop costs without the scheduler, the ports and the link counters); paired,
              ``codec ÷ zenoh`` is the codec's share of umbra's gap to raw zenoh and
              ``umbra ÷ codec`` what the rest of the framework adds;
* tcp       — a raw loopback TCP socket echo (TCP_NODELAY), the floor;
* dora      — dora-rs Python nodes, same ping-pong, ``dora run`` (skipped with the reason when
              dora-rs is not installed: ``pip install dora-rs dora-rs-cli``).

Throughput: images streamed as fast as the producer can for a few seconds, frames per second
handled by the consumer — umbra (source module -> sink module; also the frames the link delivered
to the sink's process, which keeps only the latest when the sink is slower) against raw zenoh
(put loop -> counting callback that reads the bytes).

The comparison is paired: the host is shared and its speed drifts between passes (a method's p50
can double from one pass to the next), so every method runs once in each short pass, in an order
rotated pass after pass, and umbra is compared with each baseline measured in the same pass; the
goals are judged on the median of these per-pass ratios. Pooled p50 and p99 over all passes are
reported too.

Two host conditions, each measured in every pass (their order rotated too): the host ``as-is``,
and ``tuned`` for real time — this process holds every CPU's wake-up latency at 0 through
``/dev/cpu_dma_latency`` (``umbra.runtime.realtime``, what ``umbra run --cpu-latency-us 0`` does)
while every method of the pass runs, baselines alike, so no hop starts on a CPU waking from a halt.
The tuned condition needs root; without it, it is skipped with the reason.

    python benchmarks/bench_links.py [--quick] [--host both|as-is|tuned]

Prints the pooled table, the paired ratios and the goals of each condition; writes
``benchmarks/results/links.json`` (``hosts`` -> condition -> figures).
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import shutil
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(REPO))

from benchmarks.common import plugin_env, write_results  # noqa: E402
from umbra.connectors import Input, Module, Output, Parameters, param  # noqa: E402
from umbra.connectors.messages import Image, Twist  # noqa: E402
from umbra.runtime.realtime import CpuLatencyHold  # noqa: E402

SMALL = 48
#: Seconds a raw ping-pong run may take before it is given up (a lost best-effort frame).
PINGPONG_TIMEOUT = 120.0
IMAGE_SHAPE = (480, 640, 3)
IMAGE = int(np.prod(IMAGE_SHAPE))


# -- umbra modules (registered in the child processes through an entry point) --------------------
class BenchPing(Module["BenchPing.Params"]):
    """Sends one sample, waits for it to come back, records the round trip [s]; resends a sample
    lost on a best-effort link after 1 s."""

    class Params(Parameters):
        kind: Literal["small", "image"] = param("small", "payload")
        rounds: int = param(1000, "round trips to record", gt=0)
        warmup: int = param(50, "round trips not recorded", ge=0)
        result: str = param("ping.json", "result file in the output folder")

    twist_out = Output(Twist, frame="camera", doc="ping")
    image_out = Output(Image, doc="ping")
    twist_in = Input(Twist, frame="camera", trigger=True, required=False, doc="pong")
    image_in = Input(Image, trigger=True, required=False, doc="pong")

    def start(self) -> None:
        self.rtts: list[float] = []
        self._done = 0
        self._sent_at: float | None = None
        if self.params.kind == "small":
            vector = np.arange(6, dtype=np.float64)
            self._send = lambda: self.twist_out.send(Twist(vector=vector, frame="camera"))
            self._reply = self.twist_in
        else:
            pixels = np.random.default_rng(0).integers(0, 256, IMAGE_SHAPE, dtype=np.uint8)
            self._send = lambda: self.image_out.send(Image(pixels=pixels))
            self._reply = self.image_in

    def step(self, now: float) -> None:
        t = time.perf_counter()
        if self._sent_at is not None and self._reply.fresh:
            self._done += 1
            if self._done > self.params.warmup:
                self.rtts.append(t - self._sent_at)
            self._sent_at = None
        if len(self.rtts) >= self.params.rounds:
            self.context.request_stop(f"{len(self.rtts)} round trips", 0)
            return
        if self._sent_at is None or t - self._sent_at > 1.0:
            self._sent_at = time.perf_counter()
            self._send()

    def stop(self) -> None:
        path = self.context.output_dir / self.params.result
        path.write_text(json.dumps(self.rtts))


class BenchPong(Module[Parameters]):
    """Sends every sample straight back."""

    twist_in = Input(Twist, frame="camera", trigger=True, required=False, doc="ping")
    image_in = Input(Image, trigger=True, required=False, doc="ping")
    twist_out = Output(Twist, frame="camera", doc="pong")
    image_out = Output(Image, doc="pong")

    def step(self, now: float) -> None:
        if self.twist_in.fresh:
            t = self.twist_in.value
            self.twist_out.send(Twist(vector=t.vector, frame=t.frame, stamp=t.stamp))
        if self.image_in.fresh:
            i = self.image_in.value
            self.image_out.send(Image(pixels=i.pixels, stamp=i.stamp))


class BenchSource(Module[Parameters]):
    """Sends an image every step (give it a rate it cannot keep: as fast as it goes)."""

    image = Output(Image, doc="frames")

    def start(self) -> None:
        self._pixels = np.random.default_rng(1).integers(0, 256, IMAGE_SHAPE, dtype=np.uint8)

    def step(self, now: float) -> None:
        self.image.send(Image(pixels=self._pixels))


class BenchSink(Module["BenchSink.Params"]):
    """Counts the frames it handles; writes frames per second between its first and last."""

    class Params(Parameters):
        result: str = param("sink.json", "result file in the output folder")

    image = Input(Image, trigger=True, doc="frames")

    def start(self) -> None:
        self._times: list[float] = []
        self._check = 0

    def step(self, now: float) -> None:
        frame = self.image.value
        if self.image.fresh and frame is not None:
            self._check += int(frame.pixels[0, 0, 0])  # touch the frame
            self._times.append(time.perf_counter())

    def stop(self) -> None:
        (self.context.output_dir / self.params.result).write_text(json.dumps(self._times))


ENTRY_POINTS = {
    n: f"bench_links:{n}" for n in ("BenchPing", "BenchPong", "BenchSource", "BenchSink")
}

PINGPONG_GRAPH = """
graph: bench_pingpong
clock: real
processes: {{a: {{}}, b: {{}}}}
modules:
  ping: {{type: BenchPing, process: a, rate: 10, params: {{kind: {kind}, rounds: {rounds},
          warmup: {warmup}}}}}
  pong: {{type: BenchPong, process: b}}
connections:
  - ping.{port}_out -> pong.{port}_in
  - pong.{port}_out ~> ping.{port}_in
"""
STREAM_GRAPH = """
graph: bench_stream
clock: real
processes: {a: {}, b: {}}
modules:
  source: {type: BenchSource, process: a, rate: 10000}
  sink: {type: BenchSink, process: b}
connections:
  - source.image -> sink.image
"""


def _plugin_env(tmp: Path) -> dict[str, str]:
    """The environment of ``umbra run`` with this file's modules registered (an entry point)."""
    return plugin_env(tmp, "bench-links", ENTRY_POINTS)


def _umbra(tmp: Path, graph: str, name: str, *extra: str) -> Path:
    path = tmp / f"{name}.yaml"
    path.write_text(graph)
    out = tmp / name
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "umbra.runtime.cli.main",
            "run",
            str(path),
            "--out",
            str(out),
            "--quiet",
            *extra,
        ],
        env=_plugin_env(tmp),
        capture_output=True,
        text=True,
        timeout=600,
    )
    if done.returncode != 0:
        raise RuntimeError(f"umbra run {name} failed ({done.returncode}):\n{done.stderr[-3000:]}")
    return out


def umbra_rtt(tmp: Path, kind: str, rounds: int, warmup: int, *extra: str) -> np.ndarray:
    graph = PINGPONG_GRAPH.format(
        kind=kind, rounds=rounds, warmup=warmup, port="twist" if kind == "small" else "image"
    )
    out = _umbra(tmp, graph, f"pingpong_{kind}", *extra)
    return np.array(json.loads((out / "ping.json").read_text()))


def umbra_throughput(tmp: Path, seconds: float) -> tuple[float, float]:
    """Frames per second handled by the sink module, and delivered by the link to its process
    (more than handled when the sink is slower: a best-effort link keeps the latest frame)."""
    out = _umbra(tmp, STREAM_GRAPH, "stream", "--duration", str(seconds))
    times = np.array(json.loads((out / "sink.json").read_text()))
    times = times[len(times) // 10 :]  # skip the start
    handled = (len(times) - 1) / (times[-1] - times[0])
    producer = json.loads((out / "summary-a.json").read_text())
    consumer = json.loads((out / "summary-b.json").read_text())
    delivered = consumer["links"]["subscribe"][0]["received"] / producer["wall_time_s"]
    return handled, delivered


# -- raw zenoh ---------------------------------------------------------------------------------
def _zenoh_session(listen: list[str], connect: list[str]) -> Any:
    import zenoh

    from umbra.runtime.links.config import Endpoints, build_config

    return zenoh.open(build_config(Endpoints(listen, connect)))


def _zenoh_qos(kind: str) -> dict[str, Any]:
    import zenoh

    cc = zenoh.CongestionControl.BLOCK if kind == "small" else zenoh.CongestionControl.DROP
    return {"congestion_control": cc, "express": True}


def _serve(session: Any, key: str, on_sample: Callable[[Any], None]) -> None:
    """Call ``on_sample`` for each sample on ``key``, say ``ready``, and serve until the parent
    closes stdin; then close ``session``."""
    sub = session.declare_subscriber(key, on_sample)
    sys.stdout.write("ready\n")
    sys.stdout.flush()
    sys.stdin.read()
    sub.undeclare()
    session.close()


def role_zenoh_pong(endpoint: str, kind: str) -> None:
    session = _zenoh_session([endpoint], [])
    pub = session.declare_publisher("bench/pong", **_zenoh_qos(kind))
    _serve(session, "bench/ping", lambda s: pub.put(s.payload))


def role_zenoh_sink(endpoint: str) -> None:
    session = _zenoh_session([endpoint], [])
    times: list[float] = []

    def on_frame(sample: Any) -> None:
        data = sample.payload.to_bytes()  # a consumer reads the frame
        if data[0] >= 0:
            times.append(time.perf_counter())

    _serve(session, "bench/stream", on_frame)
    t = np.array(times[len(times) // 10 :])
    rate = (len(t) - 1) / (t[-1] - t[0]) if len(t) > 2 else 0.0
    sys.stdout.write(json.dumps({"fps": rate}) + "\n")


def _child(*args: str) -> subprocess.Popen[str]:
    popen = subprocess.Popen(
        [sys.executable, __file__, *args],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
        env=dict(os.environ),
    )
    assert popen.stdout is not None
    line = popen.stdout.readline()
    if line.strip() != "ready":
        raise RuntimeError(f"helper {args} did not start: {line!r}")
    return popen


def _pingpong(
    role: tuple[str, ...], kind: str, rounds: int, warmup: int, exchange: Callable[[Any, Any], None]
) -> np.ndarray:
    """Round trips [s] against the pong started as ``role``: ``exchange(pub, sub)`` puts one
    ping and waits for its pong; the first ``warmup`` are not kept."""
    from umbra.runtime.links.config import free_loopback_ports

    endpoint = f"tcp/127.0.0.1:{free_loopback_ports(1)[0]}"
    pong = _child(*role, "--endpoint", endpoint)
    session = _zenoh_session([], [endpoint])
    try:
        pub = session.declare_publisher("bench/ping", **_zenoh_qos(kind))
        sub = session.declare_subscriber("bench/pong")
        while not pub.matching_status.matching:
            time.sleep(0.01)
        time.sleep(0.2)
        rtts: list[float] = []
        failed: list[BaseException] = []

        def rounds_loop() -> None:
            try:
                for i in range(rounds + warmup):
                    t0 = time.perf_counter()
                    exchange(pub, sub)
                    if i >= warmup:
                        rtts.append(time.perf_counter() - t0)
            except BaseException as exc:  # the session closed under it, or a bad reply
                failed.append(exc)

        # a best-effort link may drop a frame on a loaded host: then the ping would wait for
        # its pong forever; give up on this pass instead (reported as skipped, not measured)
        worker = threading.Thread(target=rounds_loop, daemon=True)
        worker.start()
        worker.join(PINGPONG_TIMEOUT)
        if worker.is_alive():
            raise RuntimeError(
                f"no pong within {PINGPONG_TIMEOUT:g} s after {len(rtts)} round trips "
                f"(a {kind} sample lost on the way)"
            )
        if failed:
            raise failed[0]
    finally:
        session.close()
        pong.communicate("", timeout=30)
    return np.array(rtts)


def zenoh_rtt(kind: str, rounds: int, warmup: int) -> np.ndarray:
    size = SMALL if kind == "small" else IMAGE
    payload = np.random.default_rng(0).integers(0, 256, size, dtype=np.uint8).tobytes()

    def exchange(pub: Any, sub: Any) -> None:
        pub.put(payload)
        sub.recv().payload.to_bytes()

    return _pingpong(("--role", "zenoh-pong", "--kind", kind), kind, rounds, warmup, exchange)


def _twist_codec() -> tuple[Callable[[bytes], Twist | None], Callable[[Twist], bytes]]:
    """Umbra's compact reader and writer of twists, as a link uses them."""
    from umbra.connectors.codec import Codec

    codec = Codec()
    read = codec.compact_reader(Twist)
    assert read is not None
    return read, codec.compact_writer(Twist)


def _echo(msg: Twist) -> Twist:
    """What ``BenchPong`` sends back (the output port then numbers it)."""
    return Twist(vector=msg.vector, frame=msg.frame, stamp=msg.stamp, seq=msg.seq + 1)


def role_codec_pong(endpoint: str) -> None:
    session = _zenoh_session([endpoint], [])
    pub = session.declare_publisher("bench/pong", **_zenoh_qos("small"))
    read, write = _twist_codec()

    def on_ping(sample: Any) -> None:
        msg = read(sample.payload.to_bytes())
        if msg is not None:
            pub.put(write(_echo(msg)))

    _serve(session, "bench/ping", on_ping)


def codec_rtt(kind: str, rounds: int, warmup: int) -> np.ndarray:
    """Raw zenoh round trips of umbra-encoded twists, decoded and re-encoded on both sides (the
    diagnostic is about the small-sample hop: twists only)."""
    if kind != "small":
        raise ValueError("the codec diagnostic runs twists only")
    read, write = _twist_codec()
    msg = Twist(vector=np.arange(6, dtype=np.float64), frame="camera", seq=1)

    def exchange(pub: Any, sub: Any) -> None:
        nonlocal msg
        pub.put(write(_echo(msg)))
        reply = read(sub.recv().payload.to_bytes())
        if reply is None:
            raise RuntimeError("the codec pong sent back something that does not decode")
        msg = reply

    return _pingpong(("--role", "codec-pong"), kind, rounds, warmup, exchange)


def zenoh_throughput(seconds: float) -> float:
    from umbra.runtime.links.config import free_loopback_ports

    endpoint = f"tcp/127.0.0.1:{free_loopback_ports(1)[0]}"
    sink = _child("--role", "zenoh-sink", "--endpoint", endpoint)
    session = _zenoh_session([], [endpoint])
    try:
        pub = session.declare_publisher("bench/stream", **_zenoh_qos("image"))
        while not pub.matching_status.matching:
            time.sleep(0.01)
        pixels = np.random.default_rng(1).integers(0, 256, IMAGE, dtype=np.uint8)
        end = time.perf_counter() + seconds
        while time.perf_counter() < end:
            frame = pixels.tobytes()  # a fresh frame's bytes each time, as a camera would
            pub.put(frame)  # (kept referenced: put(pixels.tobytes()) is ~8x slower in 1.10)
        time.sleep(0.2)
    finally:
        session.close()
    out, _ = sink.communicate("", timeout=30)
    return float(json.loads(out.strip().splitlines()[-1])["fps"])


# -- raw TCP -----------------------------------------------------------------------------------
def _recv_exact(sock: socket.socket, buf: memoryview) -> None:
    got = 0
    while got < len(buf):
        n = sock.recv_into(buf[got:])
        if n == 0:
            raise EOFError
        got += n


def role_tcp_pong(port: int) -> None:
    server = socket.create_server(("127.0.0.1", port))
    sys.stdout.write("ready\n")
    sys.stdout.flush()
    conn, _ = server.accept()
    conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    head = bytearray(4)
    buf = bytearray(IMAGE)
    try:
        while True:
            _recv_exact(conn, memoryview(head))
            (n,) = struct.unpack("<I", head)
            view = memoryview(buf)[:n]
            _recv_exact(conn, view)
            conn.sendall(head)
            conn.sendall(view)
    except (EOFError, ConnectionError):
        pass


def tcp_rtt(kind: str, rounds: int, warmup: int) -> np.ndarray:
    from umbra.runtime.links.config import free_loopback_ports

    (port,) = free_loopback_ports(1)
    pong = _child("--role", "tcp-pong", "--port", str(port))
    size = SMALL if kind == "small" else IMAGE
    payload = np.random.default_rng(0).integers(0, 256, size, dtype=np.uint8).tobytes()
    head = struct.pack("<I", size)
    back = bytearray(size + 4)
    rtts = []
    with socket.create_connection(("127.0.0.1", port)) as sock:
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        for i in range(rounds + warmup):
            t0 = time.perf_counter()
            sock.sendall(head)
            sock.sendall(payload)
            _recv_exact(sock, memoryview(back))
            if i >= warmup:
                rtts.append(time.perf_counter() - t0)
    pong.communicate("", timeout=30)
    return np.array(rtts)


# -- dora ----------------------------------------------------------------------------------------
DORA_PING = """
import json, os, time
import numpy as np, pyarrow as pa
from dora import Node
rounds, warmup, size = (int(os.environ[k]) for k in ("ROUNDS", "WARMUP", "SIZE"))
node = Node()
payload = pa.array(np.random.default_rng(0).integers(0, 256, size, dtype=np.uint8))
rtts = []
t0 = time.perf_counter()
node.send_output("ping", payload)
for event in node:
    if event["type"] == "INPUT":
        t = time.perf_counter()
        event["value"].to_numpy(zero_copy_only=False)
        rtts.append(t - t0)
        if len(rtts) >= rounds + warmup:
            break
        t0 = time.perf_counter()
        node.send_output("ping", payload)
    elif event["type"] == "STOP":
        break
json.dump(rtts[warmup:], open(os.environ["RESULT"], "w"))
"""
DORA_PONG = """
from dora import Node
node = Node()
for event in node:
    if event["type"] == "INPUT":
        node.send_output("pong", event["value"])
    elif event["type"] == "STOP":
        break
"""
DORA_FLOW = """
nodes:
  - id: ping
    path: ping.py
    inputs: {pong: pong/pong}
    outputs: [ping]
  - id: pong
    path: pong.py
    inputs: {ping: ping/ping}
    outputs: [pong]
"""


def dora_missing() -> str | None:
    if shutil.which("dora") is None:
        return "dora CLI not found (pip install dora-rs dora-rs-cli)"
    try:
        import dora  # noqa: F401
        import pyarrow  # noqa: F401
    except ImportError as exc:
        return f"dora-rs Python API not importable ({exc}); pip install dora-rs dora-rs-cli"
    return None


def dora_rtt(tmp: Path, kind: str, rounds: int, warmup: int) -> np.ndarray:
    folder = tmp / f"dora_{kind}"
    folder.mkdir(exist_ok=True)
    (folder / "ping.py").write_text(DORA_PING)
    (folder / "pong.py").write_text(DORA_PONG)
    (folder / "dataflow.yml").write_text(DORA_FLOW)
    result = folder / "rtts.json"
    env = dict(
        os.environ,
        ROUNDS=str(rounds),
        WARMUP=str(warmup),
        RESULT=str(result),
        SIZE=str(SMALL if kind == "small" else IMAGE),
    )
    done = subprocess.run(
        ["dora", "run", "dataflow.yml"],
        cwd=folder,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    if done.returncode != 0 or not result.exists():
        raise RuntimeError(f"dora run failed ({done.returncode}): {done.stderr[-2000:]}")
    return np.array(json.loads(result.read_text()))


# -- runs --------------------------------------------------------------------------------------
KINDS = ("small", "image")
METHODS = ("umbra", "noauth", "open", "zenoh", "codec", "tcp", "dora")
BASELINES = ("zenoh", "dora", "tcp")
SMALL_ONLY = ("codec",)  # diagnostics run with twists only
#: Diagnostic ratios splitting umbra's gap to raw zenoh: what the codec alone costs on raw zenoh,
#: and what the scheduler, ports and link counters add on top of the codec.
SPLIT = (("codec", "zenoh"), ("umbra", "codec"), ("umbra", "open"), ("noauth", "open"))
#: Runs of umbra with less trust, to measure what it costs (same graph, same run):
#: ``noauth`` — identity checks and size bounds on, no per-run credentials or access rules
#: (``--insecure``); ``open`` — none of them (``--insecure --unchecked-links``).
UMBRA_VARIANTS = {
    "umbra": (),
    "noauth": ("--insecure",),
    "open": ("--insecure", "--unchecked-links"),
}
LABELS = {"small": "twist 48 B", "image": "image 921 kB", "throughput": "throughput"}

Rtts = dict[str, dict[str, list[np.ndarray | None]]]  # kind -> method -> round trips [s] per pass
Fps = dict[str, list[float | None]]  # umbra, umbra_link, zenoh -> frames per second per pass


@dataclass(frozen=True)
class Plan:
    """Passes and the work in each: short passes keep the methods of a pass close in time."""

    passes: int
    rounds: dict[str, int]
    warmup: dict[str, int]
    seconds: float


def _plan(quick: bool) -> Plan:
    if quick:
        return Plan(3, {"small": 150, "image": 40}, {"small": 30, "image": 10}, 1.0)
    return Plan(7, {"small": 400, "image": 120}, {"small": 50, "image": 15}, 2.0)


def _rotated(names: list[str], p: int) -> list[str]:
    """The order of pass ``p``: no method always runs first or last."""
    k = p % len(names)
    return names[k:] + names[:k]


def _rtt(name: str, tmp: Path, kind: str, rounds: int, warmup: int) -> np.ndarray:
    if name in UMBRA_VARIANTS:
        return umbra_rtt(tmp, kind, rounds, warmup, *UMBRA_VARIANTS[name])
    if name == "zenoh":
        return zenoh_rtt(kind, rounds, warmup)
    if name == "tcp":
        return tcp_rtt(kind, rounds, warmup)
    if name == "codec":
        return codec_rtt(kind, rounds, warmup)
    return dora_rtt(tmp, kind, rounds, warmup)


def _run_pass(
    p: int,
    plan: Plan,
    tmp: Path,
    methods: list[str],
    host: str,
    rtts: Rtts,
    fps: Fps,
    skipped: dict[str, str],
) -> None:
    """Every method once, in the order of this pass; a method that fails is reported, not fatal."""
    for kind in KINDS:
        print(f"pass {p + 1}/{plan.passes}, {host} host, round trips {kind}: ", end="", flush=True)
        for name in _rotated(methods, p):
            if name in SMALL_ONLY and kind != "small":
                continue
            try:
                rtts[kind][name][p] = _rtt(name, tmp, kind, plan.rounds[kind], plan.warmup[kind])
            except Exception as exc:
                skipped[f"{name}-{kind}-{host}"] = f"pass {p + 1}: {str(exc)[:500]}"
            print(name, end=" ", flush=True)
        print()
    if not {"umbra", "zenoh"} <= set(methods):
        return
    print(f"pass {p + 1}/{plan.passes}, {host} host, throughput: ", end="", flush=True)
    for name in _rotated(["umbra", "zenoh"], p):
        try:
            if name == "umbra":
                fps["umbra"][p], fps["umbra_link"][p] = umbra_throughput(tmp, plan.seconds)
            else:
                fps["zenoh"][p] = zenoh_throughput(plan.seconds)
        except Exception as exc:
            skipped[f"{name}-throughput-{host}"] = f"pass {p + 1}: {str(exc)[:500]}"
        print(name, end=" ", flush=True)
    print()


# -- statistics --------------------------------------------------------------------------------
def _stats(rtts: np.ndarray) -> dict[str, float]:
    return {
        "p50_us": float(np.percentile(rtts, 50) * 1e6),
        "p99_us": float(np.percentile(rtts, 99) * 1e6),
        "n": int(rtts.size),
    }


def _p50_us(run: np.ndarray | None) -> float | None:
    return float(np.median(run)) * 1e6 if run is not None and run.size else None


def _median(values: list[float | None]) -> float | None:
    valid = [v for v in values if v is not None]
    return float(np.median(valid)) if valid else None


def _ratio(a: float | None, b: float | None) -> float | None:
    return a / b if a is not None and b else None


def _pooled(rtts: Rtts) -> dict[str, dict[str, Any]]:
    """p50 and p99 of each method over the round trips of all its passes."""
    pooled: dict[str, dict[str, Any]] = {}
    for kind, by_name in rtts.items():
        for name, runs in by_name.items():
            done = [r for r in runs if r is not None]
            if not done:
                continue
            stats: dict[str, Any] = _stats(np.concatenate(done))
            per_pass = [_p50_us(r) for r in runs]
            stats["p50_us_per_pass"] = [None if v is None else round(v, 1) for v in per_pass]
            pooled.setdefault(kind, {})[name] = stats
    return pooled


def _series(ratios: list[float | None]) -> dict[str, Any]:
    return {
        "per_pass": [None if r is None else round(r, 4) for r in ratios],
        "median": _median(ratios),
    }


def _paired(rtts: Rtts, fps: Fps) -> dict[str, dict[str, Any]]:
    """Per pass, umbra's p50 over each baseline's p50 of the same pass (round trips), and umbra's
    frames per second over raw zenoh's (throughput); with the median over the passes."""
    paired: dict[str, dict[str, Any]] = {}
    for kind, by_name in rtts.items():
        umbra = [_p50_us(r) for r in by_name.get("umbra", [])]
        paired[kind] = {
            base: _series(
                [_ratio(u, _p50_us(b)) for u, b in zip(umbra, by_name[base], strict=True)]
            )
            for base in BASELINES
            if base in by_name and umbra
        }
        for top, bottom in SPLIT:  # the gap to raw zenoh: the codec's share, then the rest
            if any(r is not None for r in by_name.get(top, [])) and bottom in by_name:
                paired[kind][f"{top}/{bottom}"] = _series(
                    [
                        _ratio(_p50_us(a), _p50_us(b))
                        for a, b in zip(by_name[top], by_name[bottom], strict=True)
                    ]
                )
    paired["throughput"] = {
        f"{name}/zenoh": _series(
            [_ratio(a, z) for a, z in zip(fps[name], fps["zenoh"], strict=True)]
        )
        for name in ("umbra", "umbra_link")
    }
    return paired


# name, group and key in results["paired"], whether the median ratio meets the goal
GOALS: tuple[tuple[str, str, str, Callable[[float], bool]], ...] = (
    ("small_within_1.2x_raw_zenoh", "small", "zenoh", lambda x: x <= 1.2),
    ("small_trust_costs_at_most_5pct", "small", "umbra/open", lambda x: x <= 1.05),
    ("small_faster_than_dora", "small", "dora", lambda x: x < 1.0),
    ("image_faster_than_dora", "image", "dora", lambda x: x < 1.0),
    ("image_throughput_0.8x_raw_zenoh", "throughput", "umbra/zenoh", lambda x: x >= 0.8),
    ("image_link_throughput_0.8x_raw_zenoh", "throughput", "umbra_link/zenoh", lambda x: x >= 0.8),
)


def _goals(r: dict[str, Any]) -> dict[str, Any]:
    """Each goal judged on the median of its per-pass ratios."""
    goals: dict[str, Any] = {}
    for name, group, key, met in GOALS:
        series = r["paired"].get(group, {}).get(key)
        if series is None or series["median"] is None:
            continue
        ratio = series["median"]
        goals[name] = {"ratio": ratio, "met": bool(met(ratio)), "per_pass": series["per_pass"]}
    return goals


# -- report ------------------------------------------------------------------------------------
def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="fewer passes, shorter passes")
    parser.add_argument(
        "--host",
        choices=("both", "as-is", "tuned"),
        default="both",
        help="measure the host as it is, tuned for real time (CPU wake-up latency held at 0 "
        "through /dev/cpu_dma_latency, needs root), or both, pass by pass (default)",
    )
    parser.add_argument(
        "--methods",
        help="comma-separated round-trip methods to run (default all), e.g. umbra,noauth,open "
        "for the cost of trust alone; throughput runs only when umbra and zenoh are both in",
    )
    parser.add_argument("--role", help=argparse.SUPPRESS)
    parser.add_argument("--endpoint", help=argparse.SUPPRESS)
    parser.add_argument("--kind", default="small", help=argparse.SUPPRESS)
    parser.add_argument("--port", type=int, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.role == "zenoh-pong":
        role_zenoh_pong(args.endpoint, args.kind)
        return 0
    if args.role == "zenoh-sink":
        role_zenoh_sink(args.endpoint)
        return 0
    if args.role == "codec-pong":
        role_codec_pong(args.endpoint)
        return 0
    if args.role == "tcp-pong":
        role_tcp_pong(args.port)
        return 0

    plan = _plan(args.quick)
    dora_reason = dora_missing()
    methods = [m for m in METHODS if not (m == "dora" and dora_reason)]
    if args.methods:
        wanted = args.methods.split(",")
        unknown = sorted(set(wanted) - set(METHODS))
        if unknown:
            parser.error(f"--methods: unknown {', '.join(unknown)} (known: {', '.join(METHODS)})")
        methods = [m for m in methods if m in wanted]
    results: dict[str, Any] = {"skipped": {}, "passes": plan.passes, "plan": asdict(plan)}
    if dora_reason:
        results["skipped"]["dora"] = dora_reason
    hosts = _hosts(args.host, results["skipped"])
    runs = {host: _empty_run(plan, methods) for host in hosts}
    with tempfile.TemporaryDirectory(prefix="bench_links_") as tmpdir:
        for p in range(plan.passes):
            for host in _rotated(hosts, p):
                rtts, fps = runs[host]
                with CpuLatencyHold(0 if host == "tuned" else None):
                    _run_pass(p, plan, Path(tmpdir), methods, host, rtts, fps, results["skipped"])
    results["hosts"] = {host: _summarise(*runs[host]) for host in hosts}
    _print(results)
    name = "links" if not args.methods else "links_" + "_".join(methods)
    out = write_results(name, results, quick=args.quick)
    print(f"written {out.relative_to(REPO)}")
    return 0


def _hosts(asked: str, skipped: dict[str, str]) -> list[str]:
    """The host conditions to measure: as it is, and tuned for real time (every CPU's wake-up
    latency held at 0 for every method alike) when this process may hold it."""
    hosts = ["as-is", "tuned"] if asked == "both" else [asked]
    if "tuned" in hosts:
        with CpuLatencyHold(0, logging.getLogger("bench_links")) as hold:
            if not hold.held:
                skipped["tuned"] = hold.reason
                hosts.remove("tuned")
    return hosts


def _empty_run(plan: Plan, methods: list[str]) -> tuple[Rtts, Fps]:
    rtts: Rtts = {
        kind: {
            name: [None] * plan.passes
            for name in methods
            if kind == "small" or name not in SMALL_ONLY
        }
        for kind in KINDS
    }
    fps: Fps = {name: [None] * plan.passes for name in ("umbra", "umbra_link", "zenoh")}
    return rtts, fps


def _summarise(rtts: Rtts, fps: Fps) -> dict[str, Any]:
    """Pooled figures, paired ratios and goals of one host condition."""
    r: dict[str, Any] = {
        "rtt": _pooled(rtts),
        "throughput_fps": {k: _median(v) for k, v in fps.items()},
        "throughput_fps_per_pass": fps,
        "paired": _paired(rtts, fps),
    }
    r["goals"] = _goals(r)
    return r


def _num(x: float | None, spec: str = ".2f") -> str:
    return "-" if x is None else format(x, spec)


def _print_pooled(r: dict[str, Any], passes: int) -> None:
    print()
    print(f"pooled over {passes} passes")
    print(
        f"{'round trip':<14}{'method':<8}{'p50 µs':>10}{'p99 µs':>10}{'n':>7}"
        f"{'÷ zenoh':>9}{'÷ dora':>8}{'÷ tcp':>8}"
    )
    for kind, row in r["rtt"].items():
        for name, s in row.items():
            ratios = [_num(_ratio(s["p50_us"], row.get(b, {}).get("p50_us"))) for b in BASELINES]
            print(
                f"{LABELS[kind]:<14}{name:<8}{s['p50_us']:>10.0f}{s['p99_us']:>10.0f}{s['n']:>7}"
                f"{ratios[0]:>9}{ratios[1]:>8}{ratios[2]:>8}"
            )
    fps = r["throughput_fps"]
    print(
        f"image throughput (median of passes): umbra {_num(fps.get('umbra'), '.0f')} frames/s "
        f"handled by the module ({_num(fps.get('umbra_link'), '.0f')} delivered by the link), "
        f"raw zenoh {_num(fps.get('zenoh'), '.0f')} frames/s"
    )


def _print_paired(r: dict[str, Any]) -> None:
    print()
    print("paired (median of per-pass ratios)")
    for group, by_key in r["paired"].items():
        label = LABELS[group]
        for key, s in by_key.items():
            what = key.replace("/", " ÷ ") if "/" in key else f"umbra ÷ {key}"
            per_pass = " ".join(_num(x) for x in s["per_pass"])
            print(f"{label:<14}{what:<20}{_num(s['median']):>6}   per pass: {per_pass}")
            label = ""


def _print(r: dict[str, Any]) -> None:
    for host, h in r["hosts"].items():
        print()
        held = ": every CPU's wake-up latency held at 0" if host == "tuned" else ""
        print(f"== host {host}{held}")
        _print_pooled(h, r["passes"])
        _print_paired(h)
    print()
    for name, why in r["skipped"].items():
        print(f"skipped {name}: {why}")
    for host, h in r["hosts"].items():
        for name, g in h["goals"].items():
            verdict = "met" if g["met"] else "NOT met"
            print(f"goal {name} ({host} host): ratio {g['ratio']:.2f} -> {verdict}")


if __name__ == "__main__":
    sys.exit(main())
