// Layout: panels shown / hidden (only those the graph feeds), their heights and the columns'
// split, kept per browser in localStorage; "Reset layout" forgets them. Nothing here moves the
// live video while it is in use: only showing or hiding Active Sketch does (station.css).
"use strict";
(() => {
  const KEY = "umbra.station.layout", NAMES = { video: "Live video", sketch: "Active Sketch",
    jog: "Jog", messages: "Messages", plot: "Servo errors", health: "Health", zoom: "Zoom", view3d: "3-D view" };
  let saved = {};
  try { saved = JSON.parse(localStorage.getItem(KEY) || "{}"); } catch (e) { saved = {}; }
  saved.heights = saved.heights || {};
  const store = () => localStorage.setItem(KEY, JSON.stringify(saved));
  const panels = [...document.querySelectorAll(".panel")];
  let fed = {};
  function apply() {
    // first visit: on a narrow screen the 3-D view starts hidden; Active Sketch starts hidden when
    // the page has a grab to run (shown, it takes the live video's column; a sketch-only graph
    // shows its sketch)
    if (!saved.hidden) saved.hidden = [...(innerWidth < 1600 ? ["view3d"] : []), ...(fed.controls ? ["sketch"] : [])];
    for (const p of panels) {
      const name = p.dataset.panel;
      p.hidden = !fed[name] || saved.hidden.includes(name);
      if (saved.heights[name]) p.style.height = saved.heights[name] + "px";
    }
    if (saved.left) document.documentElement.style.setProperty("--left", saved.left + "%");
    // Active Sketch shown: it takes the left column and the live video goes to the top of the
    // right column (the sketch's frame itself never moves: a moved iframe reloads)
    const video = document.querySelector('section[data-panel="video"]');
    const home = document.querySelector('section[data-panel="sketch"]').hidden ? $("col-left") : $("col-right");
    if (video.parentElement !== home) home.prepend(video);
    $("panel-list").innerHTML = "";
    for (const p of panels) {
      const name = p.dataset.panel;
      if (!fed[name]) continue;  // the graph does not feed it: not offered
      const label = document.createElement("label"), box = document.createElement("input");
      box.type = "checkbox"; box.checked = !saved.hidden.includes(name); box.dataset.panel = name;
      box.onchange = () => { saved.hidden = saved.hidden.filter((n) => n !== name); if (!box.checked) saved.hidden.push(name); store(); apply(); };
      label.append(box, " " + NAMES[name]); $("panel-list").append(label, document.createElement("br"));
    }
    umbra.emit("layout", saved);
  }
  umbra.setPanel = (name, shown) => { saved.hidden = saved.hidden.filter((n) => n !== name); if (!shown) saved.hidden.push(name); store(); apply(); };
  for (const p of panels) {
    const hide = document.createElement("button");
    hide.className = "hide"; hide.textContent = "hide"; hide.title = "hide this panel (Panels menu shows it again)";
    hide.onclick = () => umbra.setPanel(p.dataset.panel, false);
    p.querySelector("h3").append(hide);
    new ResizeObserver(() => {
      // the height the resize grip set (CSS, content box): stored as applied, so a reload keeps it
      if (!p.hidden && p.style.height) { saved.heights[p.dataset.panel] = Math.round(parseFloat(p.style.height)); store(); }
    }).observe(p);
  }
  umbra.on("state", (s) => {
    const next = JSON.stringify(s.panels);
    if (next !== JSON.stringify(fed)) { fed = s.panels; apply(); }
  });
  $("layout-reset").onclick = () => { localStorage.removeItem(KEY); location.reload(); };
  // the frame's rows have fixed heights (station.css): a text cut at a row's end is whole in
  // its tooltip, kept to the text as the panels change it
  for (const e of document.querySelectorAll("#seed-hint, #line-doing, #line-stopped, #line-tracker")) {
    new MutationObserver(() => { e.title = e.textContent; }).observe(e, { childList: true, characterData: true, subtree: true });
  }
  let dragging = false;
  $("split").addEventListener("pointerdown", (ev) => { dragging = true; $("split").setPointerCapture(ev.pointerId); });
  $("split").addEventListener("pointerup", () => { dragging = false; store(); });
  $("split").addEventListener("pointermove", (ev) => {
    if (!dragging) return;
    saved.left = Math.min(80, Math.max(30, (ev.clientX / innerWidth) * 100));
    document.documentElement.style.setProperty("--left", saved.left + "%");
  });
})();
