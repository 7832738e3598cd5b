// Servo errors plot (uPlot, vendored): a time axis in seconds of the run, x / y / z on one
// millimetre scale and roll on its own degree scale, values on hover, a chosen window length.
"use strict";
(() => {
  let chart = null, rows = [];  // [t s, x mm, y mm, z mm, roll deg], the last 120 s
  const box = $("plot");
  function make() {
    const width = Math.max(200, box.clientWidth - 4);
    return new uPlot({
      width, height: 170, legend: { live: true },
      scales: { x: { time: false }, mm: { auto: true }, deg: { auto: true } },
      axes: [
        { label: "time of the run [s]", stroke: "#aaa", grid: { stroke: "#333" }, size: 34 },
        { scale: "mm", label: "x, y, z [mm]", stroke: "#aaa", grid: { stroke: "#333" }, size: 46 },
        { scale: "deg", label: "roll [deg]", side: 1, stroke: "#fd4", grid: { show: false }, size: 46 },
      ],
      series: [
        { label: "t [s]", value: (u, v) => (v === null ? "–" : v.toFixed(1)) },
        { label: "x [mm]", scale: "mm", stroke: "#f66", value: (u, v) => (v === null ? "–" : v.toFixed(2)) },
        { label: "y [mm]", scale: "mm", stroke: "#6f6", value: (u, v) => (v === null ? "–" : v.toFixed(2)) },
        { label: "z [mm]", scale: "mm", stroke: "#69f", value: (u, v) => (v === null ? "–" : v.toFixed(2)) },
        { label: "roll [deg]", scale: "deg", stroke: "#fd4", value: (u, v) => (v === null ? "–" : v.toFixed(2)) },
      ],
    }, [[], [], [], [], []], box);
  }
  umbra.on("state", (s) => {
    // the whole history now and then, else the rows since the previous state
    if (s.errors_full) rows = s.errors.slice();
    else for (const r of s.errors) if (!rows.length || r[0] > rows[rows.length - 1][0]) rows.push(r);
    if (!rows.length || box.closest(".panel").hidden) return;
    if (!chart) chart = umbra.plot = make();
    const win = Number($("plot-window").value), t1 = rows[rows.length - 1][0];
    rows = rows.filter((r) => r[0] >= t1 - 120);
    const shown = rows.filter((r) => r[0] >= t1 - win);
    chart.setData([0, 1, 2, 3, 4].map((k) => shown.map((r) => r[k])));
    chart.setScale("x", { min: Math.max(0, t1 - win), max: Math.max(t1, win) });
  });
  new ResizeObserver(() => { if (chart) chart.setSize({ width: Math.max(200, box.clientWidth - 4), height: 170 }); }).observe(box);
})();
