// Active Sketch page: draws the server's state, drags vertices (image b's on epipolar lines),
// and posts Sketch text commands. Geometry beyond the epipolar projection is the server's.
const sk = { state: null, version: -1, snap: null, drag: null, a: [], b: [], kind: "" };
window.sketch = sk;
const NS = "http://www.w3.org/2000/svg";
const DEFAULTS = { point: [[320, 240]], line: [[220, 240], [420, 240]],
  plane: [[220, 160], [220, 320], [420, 320]], triad: [[320, 300], [440, 300], [240, 360], [320, 180]] };

function epiLine(p) {  // l = F [u, v, 1] in image b
  const F = sk.state.snapshot.F;
  return [0, 1, 2].map((i) => F[i][0] * p[0] + F[i][1] * p[1] + F[i][2]);
}
function onLine(p, a) {  // p moved onto the epipolar line of a
  const l = epiLine(a), d = (l[0] * p[0] + l[1] * p[1] + l[2]) / (l[0] * l[0] + l[1] * l[1]);
  return [p[0] - d * l[0], p[1] - d * l[1]];
}
async function send(text) {
  const r = await fetch("/sketch/command", { method: "POST", body: JSON.stringify({ text }) });
  if (!r.ok) document.getElementById("status").textContent = (await r.json()).error;
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
function draw() {
  const st = sk.state;
  for (const side of ["a", "b"]) {
    const svg = document.getElementById("svg-" + side);
    svg.innerHTML = "";
    for (const prim of st.primitives) polyline(svg, prim["reprojected_" + side], "reproj");
    if (st.path) polyline(svg, st.path["preview_" + side], "preview");
    const verts = sk[side];
    const edges = { point: [], line: [[0, 1]], plane: [[0, 1], [1, 2]], triad: [[0, 1], [0, 2], [0, 3]] }[sk.kind] || [];
    for (const [i, j] of edges) el(svg, "line", { x1: verts[i][0], y1: verts[i][1], x2: verts[j][0], y2: verts[j][1], class: "edge" });
    if (side === "b" && st.snapshot) {
      sk.a.forEach((p) => {
        const l = epiLine(p);
        el(svg, "line", { x1: 0, y1: -l[2] / l[1], x2: 640, y2: -(l[2] + 640 * l[0]) / l[1], class: "epi" });
      });
    }
    verts.forEach((p, i) => {
      const c = el(svg, "circle", { cx: p[0], cy: p[1], r: 7, class: "handle " + side, "data-testid": `handle-${side}${i}` });
      c.addEventListener("pointerdown", (ev) => { sk.drag = { side, i }; ev.preventDefault(); });
    });
  }
  document.getElementById("menu").innerHTML = "";
  for (const [name, help] of st.menu) {
    const b = document.createElement("button");
    b.textContent = name; b.title = help; b.dataset.testid = "macro-" + name;
    const last = st.primitives.length ? st.primitives[st.primitives.length - 1].id : "";
    b.onclick = () => send(`plan ${name} ${last}`.trim());
    document.getElementById("menu").appendChild(b);
  }
  const p = st.path;
  document.getElementById("plan").textContent = p ? `${p.id} ${p.macro}: ${p.ok ? "checked, " + p.duration_s.toFixed(1) + " s" : "REFUSED: " + p.reason}` : "";
  const v = st.vcr;
  document.getElementById("vcr").textContent = v ? `${v.path} ${v.mode} ${(100 * v.progress).toFixed(1)} % x${v.speed.toFixed(1)} ${v.reason}` : "";
  document.getElementById("status").textContent = st.status ? `${st.status.stage}: ${st.status.message}` : "";
}
function pointer(ev) {
  if (!sk.drag) return;
  const svg = document.getElementById("svg-" + sk.drag.side), r = svg.getBoundingClientRect();
  const p = [(ev.clientX - r.left) * 640 / r.width, (ev.clientY - r.top) * 480 / r.height];
  if (sk.drag.side === "a") {
    sk.a[sk.drag.i] = p;
    sk.b[sk.drag.i] = onLine(sk.b[sk.drag.i], p);
  } else {
    sk.b[sk.drag.i] = onLine(p, sk.a[sk.drag.i]);
  }
  draw();
}
document.addEventListener("pointermove", pointer);
document.addEventListener("pointerup", () => { sk.drag = null; });
document.getElementById("snapshot").onclick = () => send("snapshot");
document.querySelectorAll(".drop").forEach((b) => b.onclick = () => {
  if (!sk.state || !sk.state.snapshot) return;
  sk.kind = b.dataset.kind;
  sk.a = DEFAULTS[sk.kind].map((p) => p.slice());
  sk.b = sk.a.map((p) => onLine(p, p));
  draw();
});
document.getElementById("place").onclick = () => {
  const f = (pts) => pts.map((p) => `${p[0].toFixed(3)},${p[1].toFixed(3)}`).join(" ");
  if (sk.kind) send(`place ${sk.kind} ${f(sk.a)} | ${f(sk.b)}`);
};
document.querySelectorAll(".vcr").forEach((b) => b.onclick = () => send(`vcr ${b.dataset.action}`));
document.getElementById("speed").onchange = (ev) => send(`vcr speed ${ev.target.value}`);
async function poll() {
  try {
    const st = await (await fetch("/sketch/state")).json();
    if (st.version !== sk.version) {
      sk.version = st.version; sk.state = st;
      if (st.snapshot && st.snapshot.id !== sk.snap) {
        sk.snap = st.snapshot.id;
        for (const s of ["a", "b"]) document.getElementById("img-" + s).src = `/sketch/image/${s}.jpg?v=${sk.snap}`;
        sk.a = []; sk.b = []; sk.kind = "";
      }
      draw();
    }
  } finally { setTimeout(poll, 200); }
}
poll();
