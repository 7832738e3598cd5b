// Live video panel: the newest JPEG frame painted on a canvas (the server is told when, which
// measures glass-to-glass latency), the snake drawn over it in SVG, and click / drag seeds.
// The age of the picture on screen, from the camera's capture, is shown in the header and
// carried by the canvas as data-frame-age-ms: set at every paint and again every AGE_TICK_MS
// (an old picture keeps ageing while no new one comes), coloured by the console's own bounds
// (state.frame_age: amber from warn_ms, red past limit_ms, where the console refuses actions).
"use strict";
(() => {
  const SVGNS = "http://www.w3.org/2000/svg";
  const paintTimes = [];
  const AGE_TICK_MS = 100;  // how often the shown age is re-evaluated without a new frame
  const GLASS_WINDOW_MS = (umbra.glassWindowMs = 10000);  // the health panel's figures' window
  let captureWallMs = null;  // the capture of the picture on screen [ms since epoch]
  const wallMs = () => performance.timeOrigin + performance.now();
  umbra.glass = [];  // [[paint time (performance.now) ms, glass-to-glass ms]] in the window
  umbra.frameAge = () => (captureWallMs === null ? null : wallMs() - captureWallMs);
  function showAge() {  // the picture's age and the frame rate, now (both fall when frames stop)
    const t = performance.now();
    while (paintTimes.length && t - paintTimes[0] > 1000) paintTimes.shift();
    $("fps").textContent = captureWallMs === null ? "" : `${paintTimes.length} fps`;
    const age = umbra.frameAge(), el = $("frame-age");
    if (age === null || !el) return;
    $("video").dataset.frameAgeMs = Math.round(age);
    const b = umbra.state && umbra.state.frame_age;
    el.textContent = `picture ${age < 10000 ? Math.round(age) + " ms" : Math.round(age / 1000) + " s"} old`;
    el.className = !b ? "dim" : age > b.limit_ms ? "bad" : age > b.warn_ms ? "warn" : "ok";
    el.title = "age of the picture on screen, from the camera's capture" + (b ?
      `; clicks and jogs on a picture older than ${b.limit_ms} ms are refused` : "");
  }
  setInterval(showAge, AGE_TICK_MS);
  function el(tag, attrs) { const e = document.createElementNS(SVGNS, tag); for (const k in attrs) e.setAttribute(k, attrs[k]); return e; }
  umbra.drawOverlay = (svg, o) => {
    svg.querySelectorAll(".snake").forEach((e) => e.remove());
    if (!o) return;
    const g = el("g", { class: "snake", fill: "none", "stroke-width": 2, "vector-effect": "non-scaling-stroke" });
    const color = o.status === "failed" ? "#ff3030" : "#00ff40";
    // the snake's guides first, the snake over them (the inner ellipse may touch it), the marks on top
    if (o.rectangle) g.append(el("polygon", { points: o.rectangle.map((p) => p.join(",")).join(" "), stroke: "#ffd000" }));
    if (o.ellipse) {
      const e = o.ellipse;
      g.append(el("ellipse", { cx: e.cx, cy: e.cy, rx: e.rx, ry: e.ry, stroke: "#00c8ff", transform: `rotate(${e.angle_deg} ${e.cx} ${e.cy})` }));
    }
    if (o.axis) g.append(el("line", { x1: o.axis[0][0], y1: o.axis[0][1], x2: o.axis[1][0], y2: o.axis[1][1], stroke: "#ff00ff" }));
    g.append(el("polygon", { points: o.points.map((p) => p.join(",")).join(" "), stroke: color, "stroke-width": 3, id: svg.id + "-snake" }));
    if (o.centroid) g.append(el("circle", { cx: o.centroid[0], cy: o.centroid[1], r: 4, fill: "#ff00ff" }));
    for (const i of o.offending) g.append(el("circle", { cx: o.points[i][0], cy: o.points[i][1], r: 5, fill: "#ff3030", class: "offending" }));
    svg.append(g);
  };
  umbra.on("frame", async (buf) => {
    const n = new DataView(buf).getUint32(0);
    const head = JSON.parse(new TextDecoder().decode(new Uint8Array(buf, 4, n)));
    let bitmap;
    try {
      bitmap = await createImageBitmap(new Blob([new Uint8Array(buf, 4 + n)], { type: "image/jpeg" }));
    } catch (err) {  // not drawn, but answered: the server sends a frame only for an answer
      umbra.send("painted", { frame: head.frame, latency_ms: 0 });
      return;
    }
    requestAnimationFrame(() => {
      const c = $("video");
      if (head.frame < umbra.frame) { bitmap.close(); umbra.send("painted", { frame: head.frame, latency_ms: 0 }); return; }
      if (c.width !== head.w || c.height !== head.h) {
        c.width = head.w; c.height = head.h;
        $("overlay").setAttribute("viewBox", `0 0 ${head.w} ${head.h}`);
        $("video-info").textContent = `${head.w}×${head.h}`;
        document.documentElement.style.setProperty("--aspect", head.w / head.h);
      }
      c.getContext("2d").drawImage(bitmap, 0, 0);
      bitmap.close();
      umbra.frame = head.frame; umbra.size = [head.w, head.h]; umbra.painted++;
      // the capture on the server's wall clock (handed over age_ms after it), and its age now
      captureWallMs = head.handoff_wall_ms - head.age_ms;
      const latency = wallMs() - captureWallMs, t = performance.now();
      paintTimes.push(t);
      showAge();
      umbra.send("painted", { frame: head.frame, latency_ms: latency });
      umbra.latencies.push(latency);  // every paint's (the benchmarks read them by index)
      umbra.glass.push([t, latency]);
      while (umbra.glass.length && t - umbra.glass[0][0] > GLASS_WINDOW_MS) umbra.glass.shift();
    });
  });
  function fit() {  // the image's height: what is left under the commands and the dialog
    const top = $("stage").getBoundingClientRect().top - $("col-left").getBoundingClientRect().top +
                $("desk").getBoundingClientRect().top;
    document.documentElement.style.setProperty("--video-h", Math.max(160, innerHeight - top - 14) + "px");
  }
  addEventListener("resize", fit);
  umbra.on("state", (s) => { fit(); umbra.drawOverlay($("overlay"), s.overlay); });
  function imagePoint(ev) {
    const r = $("overlay").getBoundingClientRect();
    return [(ev.clientX - r.left) / r.width * umbra.size[0], (ev.clientY - r.top) / r.height * umbra.size[1]];
  }
  let down = null;
  $("overlay").addEventListener("pointerdown", (ev) => { down = imagePoint(ev); });
  $("overlay").addEventListener("pointerup", (ev) => {
    if (!down) return;
    const up = imagePoint(ev), [u0, v0] = down; down = null;
    if (Math.hypot(up[0] - u0, up[1] - v0) < 6) umbra.send("click", { u: u0, v: v0, frame: umbra.frame });
    else umbra.send("box", { u0, v0, u1: up[0], v1: up[1], frame: umbra.frame });
  });
})();
