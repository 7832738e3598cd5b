// Assistance dialog: shown when the grab asks for the operator, with the frame that caused it
// and the reason in plain words (the exact one a click away); hidden, it can be shown again.
"use strict";
(() => {
  let shown = 0, hidden = 0;
  const dialog = $("assist");
  umbra.on("state", (s) => {
    const a = s.assist;
    if (a && a.id !== shown) {
      shown = a.id;
      $("assist-reason").textContent = a.plain || a.reason; $("assist-detail").textContent = a.reason;
      $("assist-msg").textContent = "";
      // never show an earlier request's frame with this reason: clear, then draw once loaded
      const img = $("assist-img");
      img.removeAttribute("src"); umbra.drawOverlay($("assist-svg"), null);
      img.onload = () => umbra.drawOverlay($("assist-svg"), a.overlay);
      img.src = `assist.jpg?n=${a.id}`;
      $("assist-svg").setAttribute("viewBox", `0 0 ${umbra.size[0]} ${umbra.size[1]}`);
    }
    if (a && hidden !== a.id && !dialog.open) {
      dialog.show();
      if (dialog.contains(document.activeElement)) document.activeElement.blur();  // keys stay the jog's
    }
    if ((!a || umbra.ended) && dialog.open) dialog.close();
    $("assist-show").hidden = !a || dialog.open || umbra.ended;
    const mine = umbra.holds();
    dialog.querySelectorAll("[data-action]").forEach((b) => { b.disabled = !mine || umbra.ended; });
  });
  umbra.on("notice", (n) => { if (n.level === "error" && dialog.open) $("assist-msg").textContent = n.text; });
  $("assist-hide").onclick = () => { hidden = shown; dialog.close(); $("assist-show").hidden = false; };
  $("assist-show").onclick = () => { hidden = 0; dialog.show(); document.activeElement.blur(); $("assist-show").hidden = true; };
})();
