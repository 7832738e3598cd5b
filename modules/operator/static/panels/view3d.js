// 3-D panel (three.js, vendored): the arm's link frames as a chain, the wrist camera's frustum
// with the live video on it, the tool's patch, Active Sketch's items (the snapshots' frusta, the
// placed primitives, the path being played and the arm's place on it), each frame's name and the
// task's stage; drag to
// orbit, wheel to zoom. "view from" switches between that overview and the view from the
// graph's camera pose (its field of view; offered only when the graph has a camera). Drawn only
// while the panel is shown, at most 5 times a second, and not while the page is behind (its
// picture older than the console accepts actions on): a software-rendered WebGL must not take
// the live video's frames or the run's state. three.js is loaded the first
// time the panel has something to draw: a page without the panel never parses it.
"use strict";
(() => {
let THREE = null, loading = false;
const MIN_DRAW_PERIOD_MS = 200;  // at most 5 draws a second

const panel = document.querySelector('section[data-panel="view3d"]'), box = $("view3d");
let view = null;

function matrix(rows) { return new THREE.Matrix4().set(...rows); }

function make() {
  const renderer = new THREE.WebGLRenderer({ antialias: false });
  box.prepend(renderer.domElement);
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0x1d2024);
  const eye = new THREE.PerspectiveCamera(45, 1, 0.01, 20);
  eye.up.set(0, 0, 1); eye.position.set(1.1, -1.3, 0.9);
  const controls = new THREE.OrbitControls(eye, renderer.domElement);
  controls.target.set(0.35, 0, 0.25);
  controls.update();
  const grid = new THREE.GridHelper(2, 20, 0x555555, 0x333333);
  grid.rotateX(Math.PI / 2);
  scene.add(grid, new THREE.AxesHelper(0.2));
  const chain = new THREE.Line(new THREE.BufferGeometry(), new THREE.LineBasicMaterial({ color: 0x66ccff }));
  const frames = new THREE.Group(), camera = new THREE.Group(), patch = new THREE.Group();
  for (const g of [camera, patch]) g.matrixAutoUpdate = false;
  const sketch = new THREE.Group();
  scene.add(chain, frames, camera, patch, sketch);
  // the frustum's lines, and the live image on its far plane (drawn from the video canvas)
  const lines = new THREE.BufferGeometry();  // 8 segments, updated in place at each draw
  lines.setAttribute("position", new THREE.Float32BufferAttribute(new Float32Array(48), 3));
  camera.add(new THREE.LineSegments(lines, new THREE.LineBasicMaterial({ color: 0xffd000 })));
  const screen = new THREE.Mesh(new THREE.PlaneGeometry(1, 1), new THREE.MeshBasicMaterial({ side: THREE.DoubleSide }));
  screen.rotation.x = Math.PI;  // plane +y is the image's up: camera -y
  camera.add(screen, new THREE.AxesHelper(0.05));
  patch.add(new THREE.Mesh(new THREE.PlaneGeometry(1, 1), new THREE.MeshBasicMaterial({ color: 0x22bb44, side: THREE.DoubleSide })));
  controls.addEventListener("change", () => draw());
  // the view from the graph's camera: its pose (z forward, y down) turned to three.js's (-z, y up)
  const lens = new THREE.PerspectiveCamera(60, 1, 0.005, 20);
  lens.matrixAutoUpdate = false;
  return { renderer, scene, eye, lens, controls, chain, frames, camera, patch, sketch, sketchVersion: -1, video: null, size: "", screen, painted: -1, last: 0 };
}

function videoTexture() {  // the live image as a texture, made again when the image's size changes
  // a copy at most 320 px wide (the frustum is drawn small): uploading the full image at each
  // draw cost a software WebGL more than all the rest, and the live video its frames at 1280x720
  const c = $("video"), size = `${c.width}x${c.height}`;
  if (size !== view.size) {
    if (view.video) view.video.dispose();
    view.small = document.createElement("canvas");
    view.small.width = Math.min(c.width, 320); view.small.height = Math.round(view.small.width * c.height / c.width);
    view.video = new THREE.CanvasTexture(view.small);
    view.video.colorSpace = THREE.SRGBColorSpace;
    // no mipmaps, as three's VideoTexture: making them again for each new image costs a
    // software WebGL 5-7 times the rest of the draw, and the live video's frames with it
    view.video.generateMipmaps = false; view.video.minFilter = 1006;  // THREE.LinearFilter
    view.screen.material.map = view.video; view.screen.material.needsUpdate = true;
    view.size = size; view.painted = -1;  // the copy is drawn below
  }
  if (umbra.painted !== view.painted) {
    view.painted = umbra.painted;
    view.small.getContext("2d").drawImage(c, 0, 0, view.small.width, view.small.height);
    view.video.needsUpdate = true;
  }
}

// names of frames and items; a name that would cover one already placed moves down a line
const LINE_PX = 14;
function label(text, where) {
  const p = where.clone().project(view.active), w = box.clientWidth, h = box.clientHeight;
  if (p.z > 1) return;
  const x = (p.x + 1) / 2 * w, width = 7 * text.length;
  let y = (1 - p.y) / 2 * h;
  while (view.placed.some((r) => Math.abs(r.y - y) < LINE_PX && x < r.x + r.width && r.x < x + width)) y += LINE_PX;
  view.placed.push({ x, y, width });
  const div = document.createElement("div");
  div.className = "frame-name"; div.textContent = text;
  div.style.left = `${x.toFixed(0)}px`; div.style.top = `${y.toFixed(0)}px`;
  $("view3d-labels").append(div);
}

function segments(points, color) {  // a LineSegments from flat [x, y, z, x, y, z, ...] in base
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute("position", new THREE.Float32BufferAttribute(points, 3));
  return new THREE.LineSegments(geometry, new THREE.LineBasicMaterial({ color }));
}

const SNAPSHOT_DEPTH_M = 0.12;  // how far out a snapshot's frustum is drawn
function buildSketch(k) {  // Active Sketch's items, made again only when they change
  const g = view.sketch;
  g.children.forEach((o) => { o.geometry.dispose(); o.material.dispose(); });
  g.clear();
  for (const snap of k.snapshots) snap.cameras.forEach((c, i) => {
    const d = SNAPSHOT_DEPTH_M, x = d * c.tan_half_fov_x, y = x / c.aspect;
    const corners = [[x, y, d], [-x, y, d], [-x, -y, d], [x, -y, d]], seg = [];
    corners.forEach((p, j) => seg.push(0, 0, 0, ...p, ...p, ...corners[(j + 1) % 4]));
    const f = segments(seg, 0xff8c00);
    f.matrixAutoUpdate = false; f.matrix.copy(matrix(c.T));
    f.userData.label = i === 0 ? `snapshot ${snap.id}` : "";
    g.add(f);
  });
  for (const p of k.primitives) {
    const seg = [];
    if (p.edges.length) p.edges.forEach(([a, b]) => seg.push(...p.points[a], ...p.points[b]));
    else p.points.forEach(([x, y, z]) => seg.push(x - 0.01, y, z, x + 0.01, y, z, x, y - 0.01, z, x, y + 0.01, z));
    const line = segments(seg, 0xff44ff);
    line.userData.label = `${p.kind} ${p.id}`; line.userData.at = p.points[0];
    g.add(line);
  }
  if (k.path) {
    const points = k.path.points.map((q) => new THREE.Vector3(...q));
    const all = new THREE.Line(new THREE.BufferGeometry().setFromPoints(points), new THREE.LineBasicMaterial({ color: 0xbbbbbb }));
    const played = new THREE.Line(new THREE.BufferGeometry().setFromPoints(points), new THREE.LineBasicMaterial({ color: 0x33dd55 }));
    all.userData.label = `path ${k.path.macro}`; all.userData.at = k.path.points[0];
    played.name = "played";
    const marker = new THREE.Mesh(new THREE.SphereGeometry(0.012, 12, 8), new THREE.MeshBasicMaterial({ color: 0x33dd55 }));
    marker.name = "marker";
    g.add(all, played, marker);
  }
}

function drawSketch(k) {
  if (!k) { view.sketch.visible = false; return null; }
  view.sketch.visible = true;
  if (k.version !== view.sketchVersion) { view.sketchVersion = k.version; buildSketch(k); }
  for (const o of view.sketch.children) {
    if (!o.userData.label) continue;
    const at = o.userData.at ? new THREE.Vector3(...o.userData.at) : new THREE.Vector3().setFromMatrixPosition(o.matrix);
    label(o.userData.label, at);
  }
  const played = view.sketch.getObjectByName("played"), marker = view.sketch.getObjectByName("marker");
  const path = k.path, n = path ? path.points.length : 0;
  if (played) played.geometry.setDrawRange(0, path.progress === null ? 0 : 1 + Math.round(path.progress * (n - 1)));
  if (marker) {
    marker.visible = !!(path && path.at);
    if (marker.visible) { marker.position.set(...path.at); label(`${path.mode} ${Math.round(path.progress * 100)} %`, marker.position); }
  }
  return { snapshots: k.snapshots.length, primitives: k.primitives.length, path: n, at: path ? path.at : null, progress: path ? path.progress : null };
}

function draw() {
  const s = umbra.state && umbra.state.scene;
  if (!view || !s) return;
  const w = box.clientWidth, h = Math.max(120, box.clientHeight);
  view.renderer.setSize(w, h, false);
  view.renderer.domElement.style.width = "100%"; view.renderer.domElement.style.height = "100%";
  view.eye.aspect = w / h; view.eye.updateProjectionMatrix();
  const fromCamera = picker.value === "camera" && !!s.camera;
  view.active = fromCamera ? view.lens : view.eye;
  view.controls.enabled = !fromCamera;
  $("view3d-hint").hidden = fromCamera;
  $("view3d-labels").innerHTML = ""; view.placed = [];
  const points = [new THREE.Vector3(0, 0, 0)];
  s.links.forEach((l, i) => {  // one triad per link frame, made once and moved after
    const T = matrix(l.T);
    points.push(new THREE.Vector3().setFromMatrixPosition(T));
    if (i >= view.frames.children.length) {
      const made = new THREE.AxesHelper(0.06);
      made.matrixAutoUpdate = false;
      view.frames.add(made);
    }
    view.frames.children[i].matrix.copy(T);
  });
  view.frames.children.forEach((t, i) => { t.visible = i < s.links.length; });
  view.chain.geometry.setFromPoints(points);
  label(s.frame, points[0]);
  s.links.forEach((l, i) => label(l.name, points[i + 1]));
  view.camera.visible = !!s.camera && !fromCamera;  // seen from the camera: no frustum
  if (fromCamera) {  // vertical field from the horizontal one; the panel's width shows the rest
    const c = s.camera, flip = new THREE.Matrix4().makeRotationX(Math.PI);
    view.lens.matrix.copy(matrix(c.T)).multiply(flip);
    view.lens.matrixWorldNeedsUpdate = true;
    view.lens.fov = 2 * Math.atan(c.tan_half_fov_x / c.aspect) * 180 / Math.PI;
    view.lens.aspect = w / h; view.lens.updateProjectionMatrix();
  }
  if (s.camera) {
    const c = s.camera;
    view.camera.matrix.copy(matrix(c.T));
    // the image is drawn where the patch is (the frustum reaches its plane), else 10 cm out
    let d = 0.1;
    if (s.patch) {
      const there = new THREE.Vector3().setFromMatrixPosition(matrix(s.patch.T)).applyMatrix4(view.camera.matrix.clone().invert());
      if (there.z > 0.03 && there.z < 2) d = there.z;
    }
    const x = d * c.tan_half_fov_x, y = x / c.aspect;
    const corners = [[x, y], [-x, y], [-x, -y], [x, -y]].map(([a, b]) => [a, b, d]);
    const seg = [];
    corners.forEach((p, i) => { seg.push(0, 0, 0, ...p, ...p, ...corners[(i + 1) % 4]); });
    const position = view.camera.children[0].geometry.getAttribute("position");
    position.array.set(seg); position.needsUpdate = true;
    view.screen.scale.set(2 * x, 2 * y, 1); view.screen.position.set(0, 0, d);
    videoTexture();
    if (!fromCamera) label(c.name, new THREE.Vector3().setFromMatrixPosition(view.camera.matrix));
  }
  view.patch.visible = !!s.patch;
  if (s.patch) {
    view.patch.matrix.copy(matrix(s.patch.T));
    view.patch.children[0].scale.set(s.patch.size[0], s.patch.size[1], 1);
    label(s.patch.name, new THREE.Vector3().setFromMatrixPosition(view.patch.matrix));
  }
  const sketch = drawSketch(s.sketch);
  $("view3d-stage").textContent = `stage: ${umbra.state.line.stage} · ${umbra.state.line.doing}`;
  view.renderer.render(view.scene, view.active);
  const at = new THREE.Vector3().setFromMatrixPosition(view.active.matrixWorld);
  umbra.view3d = { drawn: (umbra.view3d ? umbra.view3d.drawn : 0) + 1, links: s.links.length,
    from: fromCamera ? "camera" : "overview", eye: at.toArray(), sketch,
    labels: $("view3d-labels").children.length };
}

// "view from": the overview, and the graph's camera when it has one (no camera it lacks)
const picker = $("view3d-from");
function offer(s) {
  const name = s.scene && s.scene.camera ? s.scene.camera.name : "";
  const have = picker.querySelector("option[value=camera]");
  if (name && !have) picker.add(new Option(name === "camera" ? "camera" : `camera ${name}`, "camera"));
  if (!name && have) { have.remove(); picker.value = "overview"; }
}
picker.onchange = () => { if (view) draw(); };

umbra.on("state", (s) => {
  offer(s);
  if (!s.scene || panel.hidden) return;
  if (!THREE) {
    if (!loading) { loading = true; import("../vendor/three-station.min.js").then((m) => { THREE = m; }); }
    return;
  }
  if (!view) view = make();
  // a page that is behind (its picture older than the console accepts actions on) draws no 3-D,
  // and says so: the software WebGL would take what the live video and the run's state need
  const age = umbra.frameAge(), bound = s.frame_age;
  if (age !== null && bound && age > bound.limit_ms) {
    $("view3d-stage").textContent = `3-D view paused: this page is behind (picture ${Math.round(age)} ms old)`;
    return;
  }
  const now = performance.now();
  if (now - view.last < MIN_DRAW_PERIOD_MS) return;
  view.last = now;
  draw();
});
})();
