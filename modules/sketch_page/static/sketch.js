// Active Sketch page: draws the server's state, drags vertices (image b's on epipolar lines),
// and posts Sketch text commands. Geometry beyond the epipolar projection is the server's, and
// so is control: the server refuses commands unless this browser holds it (shown on top).
const sk = { state: null, version: -1, snap: null, drag: null, a: [], b: [], kind: "", selected: null };
window.sketch = sk;
const NS = "http://www.w3.org/2000/svg";
const DEFAULTS = { point: [[320, 240]], line: [[220, 240], [420, 240]],
  plane: [[220, 160], [220, 320], [420, 320]], triad: [[320, 300], [440, 300], [240, 360], [320, 180]] };
const EDGES = { point: [], line: [[0, 1]], plane: [[0, 1], [1, 2]], triad: [[0, 1], [0, 2], [0, 3]] };
const $ = (id) => document.getElementById(id);

function epiLine(p) {  // l = F [u, v, 1] in image b
  const F = sk.state.snapshot.F;
  return [0, 1, 2].map((i) => F[i][0] * p[0] + F[i][1] * p[1] + F[i][2]);
}
function onLine(p, a) {  // p moved onto the epipolar line of a (ideal pixels: no distortion)
  const l = epiLine(a), d = (l[0] * p[0] + l[1] * p[1] + l[2]) / (l[0] * l[0] + l[1] * l[1]);
  return [p[0] - d * l[0], p[1] - d * l[1]];
}
// The epipolar CURVE of vertex i of image a in image b, distortion included, is the server's
// (GET /sketch/epipolar, one home for the camera model): a polyline, asked for whenever the
// vertex moves (one request in flight per vertex; the latest position wins).
sk.epi = [];
function curveOf(i) {
  const c = sk.epi[i], a = sk.a[i];
  return c && c.snap === sk.snap && c.at[0] === a[0] && c.at[1] === a[1] && c.points.length > 1 ? c.points : null;
}
function onCurve(p, i) {  // p moved onto the epipolar curve of a's vertex i (or its line)
  const pts = curveOf(i);
  if (!pts) return onLine(p, sk.a[i]);
  let best = pts[0], bestD = Infinity;
  for (let k = 0; k + 1 < pts.length; k++) {
    const [x0, y0] = pts[k], [x1, y1] = pts[k + 1], dx = x1 - x0, dy = y1 - y0;
    const t = Math.max(0, Math.min(1, ((p[0] - x0) * dx + (p[1] - y0) * dy) / (dx * dx + dy * dy || 1)));
    const q = [x0 + t * dx, y0 + t * dy], d = (q[0] - p[0]) ** 2 + (q[1] - p[1]) ** 2;
    if (d < bestD) { bestD = d; best = q; }
  }
  return best;
}
const epiBusy = {};
async function fetchCurve(i) {
  if (epiBusy[i]) { epiBusy[i] = "again"; return; }
  epiBusy[i] = true;
  try {
    const at = sk.a[i].slice(), snap = sk.snap;
    const r = await fetch(`/sketch/epipolar?u=${at[0]}&v=${at[1]}`);
    const reply = await r.json();
    if (r.ok && reply.snapshot === snap) {
      sk.epi[i] = { snap, at, points: reply.points };
      if (!(sk.drag && sk.drag.side === "b" && sk.drag.i === i) && sk.b[i]) sk.b[i] = onCurve(sk.b[i], i);
      draw();
    }
  } finally {
    const again = epiBusy[i] === "again";
    epiBusy[i] = false;
    if (again) fetchCurve(i);
  }
}
function imageSize(side) {  // the snapshot's image size (px), not an assumed 640 x 480
  const s = sk.state && sk.state.snapshot;
  return s ? s["size_" + side] || [s.width, s.height] : [640, 480];
}
async function post(url, body) {  // the server's answer, or its refusal, shown on the page
  const r = await fetch(url, { method: "POST", body: JSON.stringify(body) });
  const reply = await r.json().catch(() => ({ error: `HTTP ${r.status}` }));
  $("notice").textContent = $("notice").title = r.ok ? reply.message : reply.error;
  $("notice").className = r.ok ? "" : "error";
}
const send = (text) => post("/sketch/command", { text });
function drawControl(c) {
  $("holder").textContent = c.holder ? c.holder + (c.mine ? " (you)" : "") : "nobody";
  $("take").disabled = !!c.holder; $("release").disabled = !c.mine;
  $("you").textContent = c.you ? `you: ${c.you}` + (c.mine ? "" : " (watching: take control to command)") : "";
  $("refused").textContent = `${c.refused} refused`;
  document.body.classList.toggle("operator", !!c.mine);
  document.body.classList.toggle("viewer", !c.mine);
}
function el(svg, name, attrs) {
  const e = document.createElementNS(NS, name);
  for (const k in attrs) e.setAttribute(k, attrs[k]);
  svg.appendChild(e);
  return e;
}
function polyline(svg, pts, cls) {
  if (pts && pts.length) el(svg, "polyline", { points: pts.map((p) => p.join(",")).join(" "), class: cls });
}
function selectedPrimitive() {
  return (sk.state.primitives || []).find((p) => p.id === sk.selected) || null;
}
function drawPrimitive(svg, prim, side) {  // the triangulated vertices projected back
  const pts = prim["reprojected_" + side];
  if (!pts) return;
  const cls = prim.warnings && prim.warnings.length ? "reproj warned" : "reproj";
  for (const [i, j] of prim.edges) polyline(svg, [pts[i], pts[j]], cls);
  pts.forEach((p) => el(svg, "circle", { cx: p[0], cy: p[1], r: 4, class: "reproj-dot" }));
}
function drawMenu() {
  const st = sk.state, prim = selectedPrimitive();
  const menu = st.menus ? st.menus[prim ? prim.kind : "none"] : st.menu;
  $("menu").innerHTML = "";
  for (const [name, help, label] of menu) {
    const b = document.createElement("button");
    b.textContent = label || name; b.title = help; b.dataset.testid = "macro-" + name;
    b.onclick = () => send(`plan ${name} ${prim ? prim.id : ""}`.trim());
    $("menu").appendChild(b);
  }
  const sel = $("select"), ids = ["", ...st.primitives.map((p) => p.id)];
  if ([...sel.options].map((o) => o.value).join() !== ids.join()) {
    sel.innerHTML = "";
    for (const id of ids) sel.add(new Option(id || "(nothing: canned motions)", id));
  }
  sel.value = prim ? prim.id : "";
  $("aim").disabled = !prim;
  drawPrimitiveList(st.primitives);
}
// Each primitive in words, and under it its warnings (a vertex whose depth rests on where its
// handle sits along an edge running with the epipolar lines, and what to do): the server's.
function drawPrimitiveList(prims) {
  const box = $("primitives");
  box.innerHTML = "";
  for (const p of prims) {
    const row = document.createElement("div");
    row.textContent = `${p.id} ${p.kind} at ${p.centroid_m.map((x) => x.toFixed(3)).join(", ")} m, sigma ${p.sigma_mm.join(" / ")} mm`;
    box.appendChild(row);
    for (const w of p.warnings || []) {
      const warn = document.createElement("div");
      warn.className = "warning"; warn.dataset.testid = "warning-" + p.id; warn.textContent = "\u26a0 " + w;
      box.appendChild(warn);
    }
  }
}
function draw() {
  const st = sk.state;
  for (const side of ["a", "b"]) {
    const svg = $("svg-" + side);
    svg.innerHTML = "";
    for (const prim of st.primitives) drawPrimitive(svg, prim, side);
    if (st.path) polyline(svg, st.path["preview_" + side], "preview");
    const at = markerAt(st, side);
    if (at) el(svg, "circle", { cx: at[0], cy: at[1], r: 8, class: "marker", "data-testid": "marker-" + side });
    const verts = sk[side];
    for (const [i, j] of EDGES[sk.kind] || []) el(svg, "line", { x1: verts[i][0], y1: verts[i][1], x2: verts[j][0], y2: verts[j][1], class: "edge" });
    if (side === "b" && st.snapshot) {
      const w = imageSize("b")[0];
      sk.a.forEach((p, i) => {
        const pts = curveOf(i);
        if (pts) { polyline(svg, pts, "epi"); return; }
        const l = epiLine(p);  // until the curve arrives: the ideal-pixel line
        el(svg, "line", { x1: 0, y1: -l[2] / l[1], x2: w, y2: -(l[2] + w * l[0]) / l[1], class: "epi" });
      });
    }
    verts.forEach((p, i) => {
      const c = el(svg, "circle", { cx: p[0], cy: p[1], r: 7, class: "handle " + side, "data-testid": `handle-${side}${i}` });
      c.addEventListener("pointerdown", (ev) => { sk.drag = { side, i }; ev.preventDefault(); });
    });
  }
  drawMenu();
  const p = st.path;
  $("plan").textContent = p ? `${p.id} ${p.label || p.macro}: ${p.ok ? "checked, " + p.duration_s.toFixed(1) + " s" : "REFUSED: " + p.reason}` : "";
  const v = st.vcr;
  $("vcr").textContent = v ? `${v.path} ${v.mode} ${(100 * v.progress).toFixed(1)} % x${v.speed.toFixed(1)} ${v.reason}` : "";
  $("progress").value = v ? v.progress : 0;
  $("status").textContent = $("status").title = st.status ? `${st.status.stage}: ${st.status.message}` : "";
  drawCameras(st.cameras || []);
  const vd = st.verdict;
  $("verdict").textContent = vd ? `${vd.label}: ${vd.text}` : "";
  $("verdict").className = vd ? (vd.outcome === "done" ? "done" : vd.success ? "ok" : "miss") : "";
}
// Each camera's pan/tilt unit and zoom as the devices report them: slewing, zooming, or still
// where they point; a device silent past the server's bound is said to be silent, not still.
// What a device says is wrong (it is not ok) comes last on its camera's line, in red.
function drawCameras(cameras) {
  const wrong = (d) => d && !d.silent && !d.ok;
  const part = (c) => {
    const p = c.ptu, z = c.zoom, words = [], problems = [];
    if (p) words.push(p.silent ? "PTU silent" : `${p.moving ? "slewing" : "still"}, ` +
      `pan ${p.pan_deg.toFixed(1)}° tilt ${p.tilt_deg.toFixed(1)}°`);
    if (z) words.push(z.silent ? "zoom silent" : `${z.moving ? "zooming" : "zoom"} ${z.zoom.toFixed(2)}`);
    if (wrong(p)) problems.push(`PTU: ${p.status}`);
    if (wrong(z)) problems.push(`zoom: ${z.status}`);
    return `${c.side}: ${words.join(", ")}` + (problems.length ? ` | ${problems.join("; ")}` : "");
  };
  const shown = cameras.filter((c) => c.ptu || c.zoom);
  $("cameras").textContent = $("cameras").title = shown.map(part).join("\n");
  $("cameras").className = shown.some((c) => wrong(c.ptu) || wrong(c.zoom)) ? "trouble"
    : shown.every((c) => c.still) ? "dim" : "busy";
}
// Where the arm is along the previewed path: the player's progress (0..1 of the path
// parameter) interpolated between the preview's waypoints (their own s, 0..1).
function markerAt(st, side) {
  const p = st.path, v = st.vcr, pts = p && p["preview_" + side], s = p && p.preview_s;
  if (!pts || !s || !v || v.path !== p.id || pts.length !== s.length) return null;
  let k = 0;
  while (k + 2 < s.length && s[k + 1] < v.progress) k++;
  const t = Math.max(0, Math.min(1, (v.progress - s[k]) / ((s[k + 1] - s[k]) || 1)));
  const a = pts[k], b = pts[Math.min(k + 1, pts.length - 1)];
  return [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
}
function pointer(ev) {
  if (!sk.drag) return;
  const svg = $("svg-" + sk.drag.side), r = svg.getBoundingClientRect();
  const [w, h] = imageSize(sk.drag.side);
  const p = [(ev.clientX - r.left) * w / r.width, (ev.clientY - r.top) * h / r.height];
  if (sk.drag.side === "a") {
    sk.a[sk.drag.i] = p;
    sk.b[sk.drag.i] = onCurve(sk.b[sk.drag.i], sk.drag.i);
    fetchCurve(sk.drag.i);
  } else {
    sk.b[sk.drag.i] = onCurve(p, sk.drag.i);
  }
  draw();
}
document.addEventListener("pointermove", pointer);
document.addEventListener("pointerup", () => { sk.drag = null; });
$("take").onclick = () => post("/sketch/control", { action: "take" });
$("release").onclick = () => post("/sketch/control", { action: "release" });
$("snapshot").onclick = () => send("snapshot");
document.querySelectorAll(".drop").forEach((b) => b.onclick = () => {
  if (!sk.state || !sk.state.snapshot) return;
  sk.kind = b.dataset.kind;
  const [w, h] = imageSize("a");  // the defaults are for 640 x 480: scaled to the image
  sk.a = DEFAULTS[sk.kind].map((p) => [p[0] * w / 640, p[1] * h / 480]);
  sk.b = sk.a.map((p) => onLine(p, p));
  sk.epi = [];
  sk.a.forEach((_, i) => fetchCurve(i));
  draw();
});
$("place").onclick = () => {
  const f = (pts) => pts.map((p) => `${p[0].toFixed(3)},${p[1].toFixed(3)}`).join(" ");
  if (sk.kind) send(`place ${sk.kind} ${f(sk.a)} | ${f(sk.b)}`);
};
$("select").onchange = (ev) => { sk.selected = ev.target.value || null; draw(); };
const zoomValue = () => Number($("zoom").value).toFixed(2);
$("zoom-value").textContent = zoomValue();
$("zoom").oninput = () => { $("zoom-value").textContent = zoomValue(); };
$("zoom").onchange = () => send(`zoom ${zoomValue()}`);
$("aim").onclick = () => {
  const prim = selectedPrimitive();
  if (prim) send(`aim ${prim.centroid_m.join(" ")} ${zoomValue()}`);
};
document.querySelectorAll(".vcr").forEach((b) => b.onclick = () => send(`vcr ${b.dataset.action}`));
$("speed").onchange = (ev) => send(`vcr speed ${ev.target.value}`);
async function poll() {
  try {
    const st = await (await fetch("/sketch/state")).json();
    sk.control = st.control; drawControl(st.control);
    if (st.version > 0 && st.version !== sk.version) {
      const known = sk.state ? sk.state.primitives.map((p) => p.id) : [];
      sk.version = st.version; sk.state = st;
      if (st.snapshot && st.snapshot.id !== sk.snap) {
        sk.snap = st.snapshot.id;
        for (const s of ["a", "b"]) {
          $("img-" + s).onload = () => { $("empty-" + s).hidden = true; };
          $("img-" + s).src = `/sketch/image/${s}.jpg?v=${sk.snap}`;
          const [w, h] = imageSize(s);  // drawn in the image's own pixels, stretched as the image is
          $("svg-" + s).setAttribute("viewBox", `0 0 ${w} ${h}`);
          $("svg-" + s).setAttribute("preserveAspectRatio", "none");
          $("view-" + s).style.aspectRatio = `${w} / ${h}`;  // as wide as the panel, the image's aspect
        }
        sk.epi = [];
        sk.a = []; sk.b = []; sk.kind = ""; sk.selected = null;
      }
      const added = st.primitives.filter((p) => !known.includes(p.id));
      if (added.length) sk.selected = added[added.length - 1].id;  // a new primitive: selected
      draw();
    }
  } finally { setTimeout(poll, 200); }
}
poll();
// Live video of the camera the PTUs slewed to watch: the next frame is fetched off-screen and
// shown once it decoded (never a broken image); none while the graph wires no live camera.
async function live() {
  try {
    const r = await fetch(`/sketch/live/${$("live-side").value}.jpg`);
    if (r.ok) {
      const url = URL.createObjectURL(await r.blob()), img = $("live"), old = img.src;
      await new Promise((done) => { img.onload = done; img.onerror = done; img.src = url; });
      if (old && old.startsWith("blob:")) URL.revokeObjectURL(old);
      $("empty-live").hidden = true;
      const [w, h] = [img.naturalWidth, img.naturalHeight];
      if (w && h) $("view-live").style.aspectRatio = `${w} / ${h}`;
    }
  } catch (e) { /* the server is gone: the state poll says so */ }
  finally { setTimeout(live, document.hidden ? 1000 : 200); }
}
if (new URLSearchParams(location.search).get("embed") === "1") document.body.classList.add("embed");
live();
