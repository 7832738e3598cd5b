// Messages panel: the console's board (each message once, with how many times it was said and
// the exact text behind it on a click), plus what the server told this page alone. The list has
// a bounded height and scrolls inside its panel (station.css): messages never push a panel away.
"use strict";
(() => {
  let newest = 0, board = [];
  const own = [];  // notices sent on this page's socket only (malformed, slow down)
  function line(n) {
    const div = document.createElement("div");
    div.className = n.level;
    div.append(`${n.t !== undefined ? n.t.toFixed(1) + " s " : ""}${n.text}`);
    if (n.count > 1) { const c = document.createElement("span"); c.className = "count"; c.textContent = `×${n.count}`; div.append(c); }
    if (n.detail) {
      const d = document.createElement("details"), s = document.createElement("summary");
      s.textContent = " details"; d.append(s, n.detail); div.append(" ", d);
    }
    return div;
  }
  function redraw() {
    const box = $("notices"), open = new Set([...box.querySelectorAll("details[open]")].map((d) => d.parentElement.dataset.id));
    box.innerHTML = "";
    for (const n of own) box.append(line(n));
    for (const n of board) {
      const div = line(n); div.dataset.id = n.id;
      if (open.has(String(n.id))) div.querySelector("details").open = true;
      box.append(div);
    }
  }
  umbra.on("state", (s) => {
    const mine = s.notices.filter((n) => n.to === "*" || n.to === umbra.session);
    const top = mine.length ? Math.max(...mine.map((n) => n.id)) : 0;
    if (top === newest) return;
    for (const n of mine) if (n.id > newest) umbra.notices.push(n);
    newest = top; board = mine;
    redraw();
  });
  // this page's own notices: the newest 5, a repeat of the newest counted on its line (a flood
  // of "slow down" is one line); the board's lines are counted by the server
  umbra.on("notice", (n) => {
    umbra.notices.push(n);
    if (own.length && own[0].text === n.text && own[0].level === n.level) own[0].count = (own[0].count || 1) + 1;
    else { own.unshift({ ...n, count: 1 }); own.length = Math.min(own.length, 5); }
    redraw();
  });
})();
