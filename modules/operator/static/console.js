// umbra operator console: video + SVG overlay, plots, actions, dead-man jog. Everything the
// page does goes to the server as checked messages; the server decides.
"use strict";
const $ = (id) => document.getElementById(id);
const SVGNS = "http://www.w3.org/2000/svg";
const ui = (window.umbra = { painted: 0, frame: 0, size: [640, 480], state: null, notices: [],
                            session: "", latencies: [] });
let ws, seq = 0, lastNotice = 0, jogHeld = null, jogTimer = null, assistShown = 0;

function send(type, fields = {}) {
  if (!ws || ws.readyState !== 1 || !ui.session) return;
  ws.send(JSON.stringify({ session: ui.session, seq: ++seq, type, ...fields }));
}
ui.send = send;

function connect() {
  const token = new URLSearchParams(location.search).get("token");
  const url = `${location.protocol === "https:" ? "wss" : "ws"}://${location.host}/ws` +
              (token ? `?token=${encodeURIComponent(token)}` : "");
  ws = new WebSocket(url);
  ws.binaryType = "arraybuffer";
  ws.onopen = () => { $("conn").textContent = "connected"; $("conn").className = "ok"; };
  ws.onclose = () => {
    $("conn").textContent = "disconnected: reconnecting"; $("conn").className = "bad";
    ui.session = ""; seq = 0; releaseJog(); setTimeout(connect, 1000);
  };
  ws.onmessage = (ev) => (typeof ev.data === "string" ? onText(JSON.parse(ev.data)) : onFrame(ev.data));
}

// -- video: the newest frame only; report when it is painted ----------------------------
async function onFrame(buf) {
  const n = new DataView(buf).getUint32(0);
  const head = JSON.parse(new TextDecoder().decode(new Uint8Array(buf, 4, n)));
  const bitmap = await createImageBitmap(new Blob([new Uint8Array(buf, 4 + n)], { type: "image/jpeg" }));
  requestAnimationFrame(() => {
    const c = $("video");
    if (head.frame < ui.frame) { bitmap.close(); send("painted", { frame: head.frame, latency_ms: 0 }); return; }
    if (c.width !== head.w || c.height !== head.h) {
      c.width = head.w; c.height = head.h;
      $("overlay").setAttribute("viewBox", `0 0 ${head.w} ${head.h}`);
    }
    c.getContext("2d").drawImage(bitmap, 0, 0);
    bitmap.close();
    ui.frame = head.frame; ui.size = [head.w, head.h]; ui.painted++;
    const latency = performance.timeOrigin + performance.now() - head.handoff_wall_ms + head.age_ms;
    ui.latencies.push(latency);
    send("painted", { frame: head.frame, latency_ms: latency });
    fps();
  });
}
const paintTimes = [];
function fps() {
  const t = performance.now(); paintTimes.push(t);
  while (paintTimes.length && t - paintTimes[0] > 1000) paintTimes.shift();
  $("fps").textContent = `${paintTimes.length} fps`;
}

// -- state from the console ---------------------------------------------------------------
function onText(m) {
  if (m.type === "welcome") { ui.session = m.session; ui.name = m.name; send("hello", { name: m.name }); }
  else if (m.type === "notice") notice(m);
  else if (m.type === "state") render(m);
}
function notice(n) {
  ui.notices.push(n);
  const div = document.createElement("div");
  div.className = n.level; div.textContent = n.text;
  $("notices").prepend(div);
  if (n.level === "error" && $("assist").open) $("assist-msg").textContent = n.text;
}
function render(s) {
  ui.state = s;
  for (const n of s.notices) if (n.id > lastNotice) { lastNotice = n.id; if (n.to === "*" || n.to === ui.session) notice(n); }
  const mine = s.control_session && s.control_session === ui.session;
  $("holder").textContent = s.control ? s.control + (mine ? " (you)" : "") : "nobody";
  $("take").disabled = !!s.control; $("release").disabled = !mine;
  $("viewers").textContent = `${s.viewers.length} viewer(s)`;
  $("refused").textContent = s.refused ? `${s.refused} refused` : "";
  $("banner").style.display = s.banner ? "block" : "none"; $("banner").textContent = s.banner;
  $("stage-name").textContent = s.servo.stage; $("stage-msg").textContent = s.servo.message || "";
  const o = s.overlay;
  $("snake").textContent = o ? o.status + (o.reason ? `: ${o.reason}` : "") : "no contour";
  if (s.servo.reason) $("last-stop").textContent = s.servo.reason;
  $("world").textContent = s.world ? `${s.world.stage} ${s.world.message}` : "-";
  drawOverlay($("overlay"), o);
  plot(s.errors);
  $("links").innerHTML = s.links.map((l) => `<tr><td>${l.name}</td>` +
    `<td class="${!l.alive ? "bad" : l.age_ms === null || l.age_ms > 500 ? "stale" : ""}">` +
    `${l.age_ms === null ? "–" : l.age_ms + " ms"}${l.alive ? "" : " (producer gone)"}</td>` +
    `<td class="dim">${l.origin_ms === null ? "" : "data " + l.origin_ms + " ms"}</td></tr>`).join("");
  const d = s.data_age || {};
  $("data-age").innerHTML = (d.command_origin_ms === null || d.command_origin_ms === undefined ?
    "command: none passed yet" : `image → command at REG_VEL: <b class="${d.command_stale ? "bad" : ""}">` +
    `${d.command_origin_ms} ms</b>`) + " · " + (d.clocks_synced ?
    `<span class="ok">clocks in sync (±${d.clock_error_ms} ms)</span>` :
    '<span class="bad">clocks not measured yet</span>');
  $("smart").innerHTML = s.smart_alive === null ? "smart process: no data yet" :
    s.smart_alive ? '<span class="ok">smart process alive</span>' : '<span class="bad">smart process gone</span>';
  $("joints").innerHTML = s.joints.map((j) => `<tr><td>${j.name}</td><td>${j.q_deg.toFixed(1)}°</td>` +
    `<td><div class="bar"><i style="left:${(j.q_frac * 97).toFixed(0)}px"></i></div></td>` +
    `<td class="${j.qd_frac > 0.9 ? "bad" : ""}">${j.qd_deg_s.toFixed(1)}°/s of ${j.qd_max_deg_s}</td></tr>`).join("");
  $("links-extra").innerHTML = Object.entries(s.links_extra).map(([p, t]) => `<a href="${p}">${t}</a>`).join(" ");
  renderZoom(s.zoom);
  if (s.assist && s.assist.id !== assistShown) {
    assistShown = s.assist.id;
    $("assist-reason").textContent = s.assist.reason; $("assist-msg").textContent = "";
    // never show an earlier request's frame with this reason: clear, then draw once loaded
    const img = $("assist-img"), overlay = s.assist.overlay;
    img.removeAttribute("src"); drawOverlay($("assist-svg"), null);
    img.onload = () => drawOverlay($("assist-svg"), overlay);
    img.src = `assist.jpg?n=${s.assist.id}`;
    $("assist-svg").setAttribute("viewBox", `0 0 ${ui.size[0]} ${ui.size[1]}`);
    if (!$("assist").open) $("assist").show();
  }
  if (!s.assist && $("assist").open) $("assist").close();
}
function renderZoom(zooms) {
  $("zoom-section").style.display = zooms.length ? "block" : "none";
  for (const z of zooms) {
    let input = document.getElementById(`zoom-${z.name}`);
    if (!input) {
      const label = document.createElement("label");
      label.textContent = `${z.name} `;
      input = document.createElement("input");
      Object.assign(input, { id: `zoom-${z.name}`, type: "range", min: 0, max: 1, step: 0.01 });
      const shown = document.createElement("span");
      shown.id = `zoom-${z.name}-value`;
      input.addEventListener("change", () => send("zoom", { camera: z.name, value: Number(input.value) }));
      label.append(input, " ", shown); $("zoom").append(label, document.createElement("br"));
    }
    if (document.activeElement !== input) input.value = z.value;
    $(`zoom-${z.name}-value`).textContent = `${z.value.toFixed(2)} (0 wide .. 1 tele)`;
  }
}
function el(tag, attrs) { const e = document.createElementNS(SVGNS, tag); for (const k in attrs) e.setAttribute(k, attrs[k]); return e; }
function drawOverlay(svg, o) {
  svg.querySelectorAll(".snake").forEach((e) => e.remove());
  if (!o) return;
  const g = el("g", { class: "snake", fill: "none", "stroke-width": 2, "vector-effect": "non-scaling-stroke" });
  const color = o.status === "failed" ? "#ff3030" : "#00ff40";
  g.append(el("polygon", { points: o.points.map((p) => p.join(",")).join(" "), stroke: color, "stroke-width": 3, id: svg.id + "-snake" }));
  if (o.rectangle) g.append(el("polygon", { points: o.rectangle.map((p) => p.join(",")).join(" "), stroke: "#ffd000" }));
  if (o.ellipse) {
    const e = o.ellipse;
    g.append(el("ellipse", { cx: e.cx, cy: e.cy, rx: e.rx, ry: e.ry, stroke: "#00c8ff", transform: `rotate(${e.angle_deg} ${e.cx} ${e.cy})` }));
  }
  if (o.axis) g.append(el("line", { x1: o.axis[0][0], y1: o.axis[0][1], x2: o.axis[1][0], y2: o.axis[1][1], stroke: "#ff00ff" }));
  if (o.centroid) g.append(el("circle", { cx: o.centroid[0], cy: o.centroid[1], r: 4, fill: "#ff00ff" }));
  for (const i of o.offending) g.append(el("circle", { cx: o.points[i][0], cy: o.points[i][1], r: 5, fill: "#ff3030", class: "offending" }));
  svg.append(g);
}
const COLORS = ["#f66", "#6f6", "#69f", "#fd4"], NAMES = ["x mm", "y mm", "z mm", "roll deg"];
function plot(rows) {
  const svg = $("plot"); svg.innerHTML = "";
  if (!rows.length) return;
  const t0 = rows[0][0], t1 = Math.max(rows[rows.length - 1][0], t0 + 1);
  let m = 1; for (const r of rows) for (let k = 1; k < 5; k++) if (r[k] !== null) m = Math.max(m, Math.abs(r[k]));
  svg.append(el("line", { x1: 0, y1: 45, x2: 300, y2: 45, stroke: "#555" }));
  for (let k = 1; k < 5; k++) {
    const pts = rows.filter((r) => r[k] !== null).map((r) => `${((r[0] - t0) / (t1 - t0) * 300).toFixed(1)},${(45 - r[k] / m * 42).toFixed(1)}`);
    svg.append(el("polyline", { points: pts.join(" "), fill: "none", stroke: COLORS[k - 1] }));
  }
  const last = rows[rows.length - 1];
  $("err-now").innerHTML = NAMES.map((n, k) => `<span style="color:${COLORS[k]}">${n} ${last[k + 1] === null ? "–" : last[k + 1].toFixed(2)}</span>`).join(" · ") + ` (±${m.toFixed(1)})`;
}

// -- operator actions ---------------------------------------------------------------------
function imagePoint(ev) {
  const r = $("overlay").getBoundingClientRect();
  return [(ev.clientX - r.left) / r.width * ui.size[0], (ev.clientY - r.top) / r.height * ui.size[1]];
}
let down = null;
$("overlay").addEventListener("pointerdown", (ev) => { down = imagePoint(ev); });
$("overlay").addEventListener("pointerup", (ev) => {
  if (!down) return;
  const up = imagePoint(ev), [u0, v0] = down; down = null;
  if (Math.hypot(up[0] - u0, up[1] - v0) < 6) send("click", { u: u0, v: v0, frame: ui.frame });
  else send("box", { u0, v0, u1: up[0], v1: up[1], frame: ui.frame });
});
document.querySelectorAll("[data-action]").forEach((b) => b.addEventListener("click", () => send("action", { action: b.dataset.action })));
$("take").onclick = () => send("take");
$("release").onclick = () => send("release");
$("assist-hide").onclick = () => $("assist").close();

// jog: keep-alive every 40 ms while held (the console forwards each to REG_VEL, whose 0.1 s
// watchdog stops a jog whose keep-alives stop); release on up, leave, blur, hide, unload
function jogSend(held) {
  send("jog", { held, axes: jogHeld || [0, 0, 0, 0], jog_frame: $("jog-frame").value, speed: Number($("jog-speed").value), frame: ui.frame || 0 });
}
function holdJog(axis, sign) {
  jogHeld = [0, 0, 0, 0]; jogHeld[axis] = sign; jogSend(true);
  clearInterval(jogTimer); jogTimer = setInterval(() => jogSend(true), 40);
}
function releaseJog() {
  if (jogTimer) { clearInterval(jogTimer); jogTimer = null; }
  if (jogHeld) { jogSend(false); jogHeld = null; }
}
ui.holdJog = holdJog; ui.releaseJog = releaseJog;
document.querySelectorAll("#jog button").forEach((b) => {
  b.addEventListener("pointerdown", (ev) => { b.setPointerCapture(ev.pointerId); holdJog(+b.dataset.axis, +b.dataset.sign); });
  for (const e of ["pointerup", "pointercancel", "lostpointercapture"]) b.addEventListener(e, releaseJog);
});
const KEYS = { ArrowRight: [0, 1], ArrowLeft: [0, -1], ArrowDown: [1, 1], ArrowUp: [1, -1],
               PageDown: [2, 1], PageUp: [2, -1], e: [3, 1], q: [3, -1] };
addEventListener("keydown", (ev) => { const k = KEYS[ev.key]; if (k && !ev.repeat) { ev.preventDefault(); holdJog(...k); } });
addEventListener("keyup", (ev) => { if (KEYS[ev.key]) releaseJog(); });
addEventListener("blur", releaseJog);
addEventListener("pagehide", releaseJog);
document.addEventListener("visibilitychange", () => { if (document.hidden) releaseJog(); });
connect();
