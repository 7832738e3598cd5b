// Jog pad: buttons named by where they take the camera in the live image (the frame and axis
// beneath), held to move: a keep-alive at the console's period (state.jog_keepalive_ms);
// released on up, blur, hide or unload. A hold the console stopped (a picture too old, or
// keep-alives too late, the guard held it) stays stopped until released: the pad says why in the
// words of the console's code (state.jog_stopped.words), its exact text on hover.
"use strict";
(() => {
  let held = null, timer = null, drawn = "";
  function jogSend(isHeld) {
    umbra.send("jog", { held: isHeld, axes: held || [0, 0, 0, 0], jog_frame: $("jog-frame").value,
                        speed: Number($("jog-speed").value), frame: umbra.frame || 0 });
    hint();
  }
  // the pad's line: why a held jog stopped (the console's words), or, while held on a picture
  // older than the console's bound, that it will be refused (said at once, even when the
  // console is too busy to answer), else the frame the buttons move in
  function hint() {
    const s = umbra.state, el = $("jog-hint");
    if (!s) return;
    const age = umbra.frameAge(), b = s.frame_age, stopped = umbra.holds() && s.jog_stopped;
    const old = held && b && age !== null && age > b.limit_ms;
    el.textContent = stopped ? `${s.jog_stopped.words} · release and press again` : old ?
      `jog: your picture is ${Math.round(age)} ms old; jogs on a picture older than ${b.limit_ms} ms are refused` :
      `${$("jog-frame").value} frame · as seen in the live image`;
    el.className = stopped || old ? "bad" : "dim";
    el.title = stopped ? s.jog_stopped.detail : "";
  }
  function holdJog(axis, sign) {
    if (!umbra.state) return;  // no word from the console yet (its keep-alive period)
    held = [0, 0, 0, 0]; held[axis] = sign; jogSend(true);
    clearInterval(timer); timer = setInterval(() => jogSend(true), umbra.state.jog_keepalive_ms);
  }
  function releaseJog() {
    if (timer) { clearInterval(timer); timer = null; }
    if (held) { jogSend(false); held = null; hint(); }
  }
  umbra.holdJog = holdJog; umbra.releaseJog = releaseJog;
  function draw(labels) {
    const pad = $("jog"); pad.innerHTML = "";
    for (const j of labels) {
      const b = document.createElement("button");
      b.dataset.axis = j.axis; b.dataset.sign = j.sign;
      b.innerHTML = `${j.label}<small>${j.axis_name}</small>`;
      b.addEventListener("pointerdown", (ev) => { b.setPointerCapture(ev.pointerId); holdJog(j.axis, j.sign); });
      for (const e of ["pointerup", "pointercancel", "lostpointercapture"]) b.addEventListener(e, releaseJog);
      pad.append(b);
    }
  }
  umbra.on("state", (s) => {
    const frame = $("jog-frame").value, labels = s.jog_labels[frame] || [];
    const key = frame + JSON.stringify(labels);
    if (key !== drawn) { drawn = key; draw(labels); }
    hint();
    for (const b of $("jog").querySelectorAll("button")) b.disabled = !umbra.holds() || umbra.ended;
  });
  $("jog-frame").addEventListener("change", () => { releaseJog(); if (umbra.state) umbra.emit("state", umbra.state); });
  const KEYS = { ArrowRight: [0, 1], ArrowLeft: [0, -1], ArrowDown: [1, 1], ArrowUp: [1, -1],
                 PageDown: [2, 1], PageUp: [2, -1], e: [3, 1], q: [3, -1] };
  addEventListener("keydown", (ev) => { const k = KEYS[ev.key]; if (k && !ev.repeat && ev.target.tagName !== "SELECT") { ev.preventDefault(); holdJog(...k); } });
  addEventListener("keyup", (ev) => { if (KEYS[ev.key]) releaseJog(); });
  addEventListener("blur", releaseJog);
  addEventListener("pagehide", releaseJog);
  document.addEventListener("visibilitychange", () => { if (document.hidden) releaseJog(); });
  umbra.on("connection", () => releaseJog());
})();
