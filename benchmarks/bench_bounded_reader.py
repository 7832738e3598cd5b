"""What bounding every chunk costs a reader: umbra's recording reader against the mcap library's.

The same recording is read through by both (every record, every CRC checked): baseline, the
``mcap`` library's ``StreamReader``, which inflates a whole chunk whatever its header says;
measured, :func:`umbra.runtime.recording.reader.read_records`, which checks each chunk's declared
size before inflating it and stops at it (:mod:`umbra.runtime.recording.chunks`). Two recordings of
a camera at 640x480 (raw pixels, incompressible) with a 600 Hz scalar beside it: one in LZ4 chunks,
one stored. Best wall time of ``--repeats`` reads, the two readers interleaved.

    python benchmarks/bench_bounded_reader.py [--quick]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.common import table, write_results  # noqa: E402


def recording(path: Path, compress: bool, frames: int) -> Path:
    """``frames`` raw camera images and 20 scalars per frame, recorded by the recorder."""
    from umbra.connectors.messages import Image, Scalar
    from umbra.runtime.recording.writer import RecordingFile

    rec = RecordingFile(path, blocking=True, compress=compress)
    pixels = np.random.default_rng(0).integers(0, 255, (480, 640, 3), dtype=np.uint8)
    for i in range(frames):
        rec.offer("/cam/image", Image(pixels=pixels, frame="cam", stamp=i / 30, seq=i + 1), i / 30)
        for k in range(20):
            t = i / 30 + k / 600
            rec.offer("/s/value", Scalar(value=float(k), stamp=t, seq=i * 20 + k + 1), t)
    rec.close()
    return path


def best_reads(path: Path, repeats: int) -> dict[str, float]:
    """Best wall time [ms] of each reader over ``repeats`` interleaved reads."""
    from mcap.stream_reader import StreamReader

    from umbra.runtime.recording.reader import read_records

    def library() -> int:
        with open(path, "rb") as f:
            return sum(1 for _ in StreamReader(f, validate_crcs=True).records)

    def bounded() -> int:
        return sum(1 for _ in read_records(path))

    best = {"mcap library (baseline)": float("inf"), "umbra bounded reader": float("inf")}
    for _ in range(repeats):
        for name, read in zip(best, (library, bounded), strict=True):
            started = time.perf_counter()
            read()
            best[name] = min(best[name], (time.perf_counter() - started) * 1e3)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a shorter recording, fewer reads")
    args = parser.parse_args()
    frames, repeats = (40, 3) if args.quick else (150, 7)
    folder = Path(tempfile.mkdtemp(prefix="bench_reader_"))
    rows, results = [], {}
    for label, compress in (("lz4", True), ("stored", False)):
        path = recording(folder / f"{label}.mcap", compress, frames)
        best = best_reads(path, repeats)
        base = best["mcap library (baseline)"]
        for name, ms in best.items():
            rows.append([f"{label}: {name}", ms, ms / base])
        results[label] = {
            "bytes": path.stat().st_size,
            **{name: ms for name, ms in best.items()},
            "bounded_x_baseline": best["umbra bounded reader"] / base,
        }
    print(f"\n{frames} frames 640x480 raw + 20 scalars each; best of {repeats} reads")
    print(table(rows, ["", "best ms", "x baseline"]))
    path = write_results(
        "bounded_reader", {"frames": frames, "repeats": repeats, **results}, quick=args.quick
    )
    print(f"\nwrote {path}")


if __name__ == "__main__":
    main()
