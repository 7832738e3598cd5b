"""Per-module run counters and the end-of-run summary a person can read."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass
class ModuleStats:
    """Calls, step time [ns] and deadline misses of one module."""

    name: str
    type_name: str
    calls: int = 0
    total_ns: int = 0
    max_ns: int = 0
    misses: int = 0
    violations: int = 0
    extra: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        mean_us = self.total_ns / self.calls / 1e3 if self.calls else 0.0
        return {
            "module": self.name,
            "type": self.type_name,
            "calls": self.calls,
            "mean_step_us": round(mean_us, 3),
            "max_step_us": round(self.max_ns / 1e3, 3),
            "misses": self.misses,
            "stale_samples": self.violations,
            **self.extra,
        }


@dataclass
class RunResult:
    """How a process's run ended, with its counters."""

    process: str
    exit_code: int
    reason: str
    ticks: int
    sim_time: float
    wall_time: float
    modules: list[ModuleStats]
    lateness_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    extra: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        late = self.lateness_s
        timing = {}
        if late.size:
            timing = {
                "lateness_p50_ms": float(np.percentile(late, 50) * 1e3),
                "lateness_p99_ms": float(np.percentile(late, 99) * 1e3),
                "lateness_max_ms": float(late.max() * 1e3),
            }
        return {
            "process": self.process,
            "exit_code": self.exit_code,
            "reason": self.reason,
            "ticks": self.ticks,
            "clock_time_s": round(self.sim_time, 6),
            "wall_time_s": round(self.wall_time, 3),
            **timing,
            "modules": [m.as_dict() for m in self.modules],
            **self.extra,
        }

    def table(self) -> str:
        """The summary table printed when a run ends."""
        rows = [("module", "type", "calls", "mean µs", "max µs", "misses", "stale")]
        for m in self.modules:
            d = m.as_dict()
            rows.append(
                (
                    m.name,
                    m.type_name,
                    str(m.calls),
                    f"{d['mean_step_us']:.1f}",
                    f"{d['max_step_us']:.1f}",
                    str(m.misses),
                    str(m.violations),
                )
            )
        widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
        lines = [
            f"process `{self.process}`: {self.reason} after {self.ticks} ticks, "
            f"{self.sim_time:.3f} s clock time, {self.wall_time:.2f} s wall time"
        ]
        for i, row in enumerate(rows):
            lines.append(
                "  "
                + "  ".join(
                    c.ljust(w) if j < 2 else c.rjust(w)
                    for j, (c, w) in enumerate(zip(row, widths, strict=True))
                )
            )
            if i == 0:
                lines.append("  " + "  ".join("-" * w for w in widths))
        for m in self.modules:
            for key, value in m.extra.items():
                text = str(value)
                if len(text) > 160:
                    text = text[:150] + f"... ({len(text)} characters, see summary.json)"
                lines.append(f"  {m.name}.{key}: {text}")
        return "\n".join(lines)
