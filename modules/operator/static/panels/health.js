// Health panel: this page's own glass-to-glass figure (camera capture to paint, p50 / p95 of
// the last seconds' frames, measured by the video panel), each link's age (from its producer's
// stamp) and data age (from the sensor), the image-to-command age at REG_VEL, whether the
// clocks agree and the servo process lives, joints.
// Once the run has ended, processes gone and links silent are its end, not faults: said in grey.
"use strict";
umbra.glassFigures = () => {  // {p50, p95, n} [ms] of the frames painted in the last seconds
  const ms = umbra.glass.map((p) => p[1]).sort((a, b) => a - b);
  const at = (q) => ms[Math.min(ms.length - 1, Math.floor(q * ms.length))];
  return ms.length ? { p50: Math.round(at(0.5)), p95: Math.round(at(0.95)), n: ms.length } : null;
};
umbra.on("state", (s) => {
  const g = umbra.glassFigures(), b = s.frame_age;
  const cls = (ms) => (!b ? "" : ms > b.limit_ms ? "bad" : ms > b.warn_ms ? "warn" : "ok");
  $("glass").innerHTML = !g ? "this page: no picture painted yet" :
    `this page, capture → paint: p50 <b class="${cls(g.p50)}">${g.p50} ms</b> · ` +
    `p95 <b class="${cls(g.p95)}">${g.p95} ms</b> <span class="dim">(${g.n} frames, last ${umbra.glassWindowMs / 1000} s)</span>`;
  const ended = s.phase === "ended", bad = ended ? "dim" : "bad";
  $("links").innerHTML = s.links.map((l) => `<tr><td>${l.name}</td>` +
    `<td class="${!l.alive ? bad : l.age_ms === null || l.age_ms > 500 ? "stale" : ""}">` +
    `${l.age_ms === null ? "–" : l.age_ms + " ms"}${l.alive ? "" : ended ? " (run ended)" : " (producer gone)"}</td>` +
    `<td class="dim">${l.origin_ms === null ? "" : "data " + l.origin_ms + " ms"}</td></tr>`).join("");
  const d = s.data_age || {};
  $("data-age").innerHTML = (d.command_origin_ms === null || d.command_origin_ms === undefined ?
    "command: none passed yet" : `image → command at REG_VEL: <b class="${d.command_stale ? "bad" : ""}">` +
    `${d.command_origin_ms} ms</b>`) + " · " + (d.clocks_synced ?
    `<span class="ok">clocks in sync (±${d.clock_error_ms} ms)</span>` :
    `<span class="${bad}" id="clock-problem"></span>`);
  const why = $("clock-problem");
  if (why) why.textContent = d.clock_problem ? `clocks cannot be dated: ${d.clock_problem}` :
    "clocks not measured yet";
  $("smart").innerHTML = s.smart_alive === null ? "smart process: no data yet" :
    s.smart_alive ? '<span class="ok">smart process alive</span>' :
    ended ? '<span class="dim">smart process: ended with the run</span>' : '<span class="bad">smart process gone</span>';
  $("joints").innerHTML = s.joints.map((j) => `<tr><td>${j.name}</td><td>${j.q_deg.toFixed(1)}°</td>` +
    `<td><div class="bar"><i style="left:${(j.q_frac * 87).toFixed(0)}px"></i></div></td>` +
    `<td class="${j.qd_frac > 0.9 ? "bad" : ""}">${j.qd_deg_s.toFixed(1)}°/s of ${j.qd_max_deg_s}</td></tr>`).join("");
});
