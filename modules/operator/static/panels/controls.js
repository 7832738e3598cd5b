// Controls and the state line: control (take / release), the grab's commands enabled only when
// they would do something, the one state line, the red "arm held" banner, and the run's end.
"use strict";
(() => {
  const conn = $("conn");
  umbra.on("connection", (text) => { conn.textContent = text; conn.className = "pill " + (text === "connected" ? "ok" : "bad"); });
  document.querySelectorAll("[data-action]").forEach((b) =>
    b.addEventListener("click", () => umbra.send("action", { action: b.dataset.action })));
  $("take").onclick = () => umbra.send("take");
  $("release").onclick = () => umbra.send("release");
  function render(s) {
    const mine = umbra.holds(), over = umbra.ended || s.phase === "ended";
    $("holder").textContent = s.control ? s.control + (mine ? " (you)" : "") : "nobody";
    $("take").disabled = !!s.control || over; $("release").disabled = !mine || over;
    $("viewers").textContent = `${s.viewers.length} viewer(s)`;
    $("refused").textContent = s.refused ? `${s.refused} refused from pages without control` : "";
    for (const b of document.querySelectorAll("#commands [data-action]")) b.disabled = !(mine && s.commands[b.dataset.action]) || umbra.ended;
    $("commands").hidden = !s.panels.controls;
    const l = s.line;
    $("line-phase").textContent = umbra.ended ? "ended" : l.phase;
    $("line-phase").className = "pill " + ({ running: "ok", ended: "ended" }[umbra.ended ? "ended" : l.phase] || "");
    $("line-stage").textContent = l.stage;
    $("line-doing").textContent = `${l.doing ? "· " + l.doing + " " : ""}· control: ${l.control}`;
    // the reason the arm is held is said once: in the red banner while it holds, else here
    const held = s.banner && !umbra.ended;
    $("line-stopped").textContent = l.stopped && !held ? `· arm stopped: ${l.stopped}` : "";
    $("line-tracker").textContent = l.tracker && !umbra.ended ? `· ${l.tracker}` : "";
    // what a click on the patch does now: the console's words, for this page's control
    $("click-does").textContent = mine || s.phase === "ended" ? l.click : l.click_without_control;
    const det = $("line-detail");
    det.hidden = !l.stopped_detail || l.stopped_detail === l.stopped;
    det.querySelector("span").textContent = l.stopped_detail;
    $("line-verdict").innerHTML = "";
    if (l.verdict) {
      const b = document.createElement("b");
      b.className = { succeeded: "grasped", stopped: "stopped" }[l.outcome] || "missed";
      b.textContent = `verdict: ${l.verdict}`;
      $("line-verdict").append(b);
    }
    // the banner's line is always there (a banner that came and went moved the live image, and
    // a click, by a line): red while the arm is held, a dim "not held" otherwise
    $("banner").className = !held ? "free" : l.stage === "done" ? "calm" : "";  // calm: held, grab done
    const why = s.assist && l.stage === "assist" ? "the grab asks for you (the request is below)" : l.stopped || s.banner;
    $("banner").textContent = held ? `arm held at zero: ${why}` : umbra.ended ? "" : "arm not held";
    $("banner").title = $("banner").textContent;  // one line, cut at the page's edge: all of it
    $("banner").hidden = umbra.ended;  // the ended page is no longer live: nothing moves under a click
  }
  umbra.on("state", render);
  umbra.on("ended", (s) => {
    render(s);
    conn.textContent = "run ended"; conn.className = "pill ended";
    const w = s.world, summary = w && w.values ? Object.entries(w.values)
      .filter(([k]) => k !== "grasped").map(([k, v]) => `${k.replace(/_/g, " ")} ${v}`).join(" · ") : "";
    $("ended").hidden = false;
    $("ended").textContent = `The run has ended: ${s.line.verdict || "no verdict (the run was stopped before the grab was judged)"}` +
      (summary ? ` — ${summary}` : "") + ". This page is no longer live; start a new run for a new address.";
    document.querySelectorAll("button, select, input").forEach((e) => { if (e.id !== "layout-reset") e.disabled = true; });
  });
})();
