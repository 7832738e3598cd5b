"""What the console's web side measured, for the module's summary (pure; no web imports, so a
console that does not serve imports no web code)."""

from __future__ import annotations

from typing import Any

import numpy as np

from umbra.modules.operator.cpu import process_cpu_s, thread_cpu_s


def web_figures(stats: Any, seed_sent_wall: list[tuple[float, float]]) -> dict[str, object]:
    """Frames, viewers, refused and closed sockets, glass-to-glass latency [ms], click to seed
    [ms] and frames shown per second, from the web side's ``WebStats``."""
    lat = np.asarray(stats.latency_ms)
    out: dict[str, object] = {
        "frames_encoded": stats.frames_encoded,
        "frames_sent": stats.frames_sent,
        "frames_painted": len(lat),
        "viewers_max": stats.viewers_max,
        "malformed": stats.malformed,
        "replayed": stats.replayed,
        "closed_abusers": stats.closed_abusers,
        "oversize": stats.oversize,
        "lane_full": stats.lane_full,
    }
    if len(lat):
        out["latency_p50_ms"] = round(float(np.percentile(lat, 50)), 2)
        out["latency_p95_ms"] = round(float(np.percentile(lat, 95)), 2)
    if seed_sent_wall:
        waits = np.array([(sent - got) * 1e3 for got, sent in seed_sent_wall])
        out["seed_latency_p50_ms"] = round(float(np.percentile(waits, 50)), 2)
        out["seed_latency_p95_ms"] = round(float(np.percentile(waits, 95)), 2)
    if len(stats.painted_wall) > 1:
        span = stats.painted_wall[-1] - stats.painted_wall[0]
        out["fps_shown"] = round((len(stats.painted_wall) - 1) / span, 2) if span > 0 else 0.0
    return out


def cpu_figures(stats: Any, cpu0: float) -> dict[str, float]:
    """CPU seconds of the web thread, of the JPEG encoder thread, and of the whole process since
    ``cpu0`` (its CPU seconds when the console started)."""
    web = thread_cpu_s(stats.web_tid) if stats.web_tid else 0.0
    enc = thread_cpu_s(stats.encoder_tid) if stats.encoder_tid else 0.0
    return {
        "web_cpu_s": round(web, 3),
        "encoder_cpu_s": round(enc, 3),
        "process_cpu_s": round(process_cpu_s() - cpu0, 3),
    }
