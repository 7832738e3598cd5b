"""StatusPlot: plots named figures of a Status stream over time into a PNG when the run ends.

For the tool pick-up this is the convergence plot of vsServo's errors (x, y, z in mm, roll in
degrees); any module that puts figures in ``Status.values`` can be plotted the same way.
"""

from __future__ import annotations

from collections import defaultdict

from umbra.connectors import Input, Module, Parameters, param
from umbra.connectors.messages import Status
from umbra.connectors.params import RunFile


class StatusPlot(Module["StatusPlot.Params"]):
    """Collects ``values`` of each new Status and writes them as a PNG plot at the end."""

    class Params(Parameters):
        keys: list[str] = param([], "figures to plot (empty: every figure seen)", tunable=True)
        scale: dict[str, float] = param(
            {}, "multiply a figure before plotting, e.g. m -> mm: 1000", tunable=True
        )
        units: dict[str, str] = param({}, "unit shown in the legend per figure")
        path: RunFile = param(
            "plot.png", "PNG file, relative to the run's output folder (empty: none)"
        )
        title: str = param("", "plot title (default: the module name)", tunable=True)

    status = Input(Status, trigger=True, doc="status stream with figures in `values`")

    def start(self) -> None:
        self._t0: float | None = None
        self._series: dict[str, list[tuple[float, float]]] = defaultdict(list)
        self._stages: list[tuple[float, str]] = []
        self.path = self.context.output_dir / self.params.path

    def step(self, now: float) -> None:
        sample = self.status.get(now)
        if sample is None or not self.status.fresh:
            return
        if self._t0 is None:
            self._t0 = now
        t = now - self._t0
        if not self._stages or self._stages[-1][1] != sample.stage:
            self._stages.append((t, sample.stage))
        wanted = self.params.keys or list(sample.values)
        for key in wanted:
            if key in sample.values:
                self._series[key].append((t, sample.values[key] * self.params.scale.get(key, 1.0)))

    def stop(self) -> None:
        if not self._series or not self.params.path:
            return
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(8, 4.5), dpi=100)
        for key, points in self._series.items():
            times, values = zip(*points, strict=True)
            unit = self.params.units.get(key, "")
            ax.plot(times, values, label=f"{key} [{unit}]" if unit else key, linewidth=1.4)
        for t, stage in self._stages:
            ax.axvline(t, color="0.7", linewidth=0.8, linestyle="--")
            ax.text(
                t,
                1.0,
                f" {stage}",
                transform=ax.get_xaxis_transform(),
                fontsize=8,
                va="top",
                rotation=90,
                color="0.4",
            )
        ax.axhline(0.0, color="black", linewidth=0.6)
        ax.set_xlabel("time [s]")
        ax.set_title(self.params.title or self.name)
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize=8)
        fig.tight_layout()
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(self.path)
        plt.close(fig)

    def summary(self) -> dict[str, object]:
        points = sum(len(v) for v in self._series.values())
        written = points and self.params.path
        return {"plot": str(self.path) if written else "", "points": points}
