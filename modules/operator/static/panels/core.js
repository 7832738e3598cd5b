// umbra station core: the page's one socket and a small bus the panels subscribe to. Every
// action goes to the server as a checked message; the server decides. A lost socket is opened
// again every second; the server's first word on a socket is its latest state, so a page whose
// socket was cut at the run's end learns the end and its verdict when it reconnects (the server
// serves on for a while after the run).
"use strict";
const $ = (id) => document.getElementById(id);
const umbra = (window.umbra = { painted: 0, frame: 0, size: [640, 480], state: null, notices: [],
  session: "", name: "", latencies: [], ended: false, handlers: {} });
let socket = null, seq = 0;
// how long [s] the page waits without hearing from the run (the console's PAGE_SILENT_S, sent in
// its welcome; 0 before the first): a closed socket that does not come back is then said to be a
// run that may be gone; an open socket that stays silent (the server sends its state at least
// twice in that time) is dropped and another opened, so that a connection that lost its
// messages without closing (a half-open one) cannot hold the page on a live-looking state
umbra.silentS = 0;

umbra.on = (kind, fn) => { (umbra.handlers[kind] = umbra.handlers[kind] || []).push(fn); };
umbra.emit = (kind, data) => { for (const fn of umbra.handlers[kind] || []) fn(data); };
const post = (type, fields) => {
  if (!socket || socket.readyState !== 1 || !umbra.session) return;
  socket.send(JSON.stringify({ session: umbra.session, seq: ++seq, type, ...fields }));
};
umbra.send = (type, fields = {}) => { if (!umbra.ended) post(type, fields); };
// the page has drawn state `version`: the server sends the next one only then (never a queue),
// and waits for it to know the run's end was shown (said after the end too, unlike umbra.send)
const seen = (version) => { if (Number.isInteger(version)) post("seen", { state: version }); };
umbra.holds = () => !!(umbra.state && umbra.state.control_session &&
                       umbra.state.control_session === umbra.session);

umbra.connect = () => {
  const token = new URLSearchParams(location.search).get("token");
  const url = `${location.protocol === "https:" ? "wss" : "ws"}://${location.host}/ws` +
              (token ? `?token=${encodeURIComponent(token)}` : "");
  socket = new WebSocket(url);
  socket.binaryType = "arraybuffer";
  socket.onopen = () => { umbra.lostAt = 0; umbra.heardAt = performance.now(); umbra.emit("connection", "connected"); };
  socket.onclose = () => {
    const hadSession = umbra.session !== "";
    umbra.session = ""; seq = 0;
    if (umbra.ended) return;  // the run's end was said: nothing more to hear
    // a run that died without saying so: after silentS the page says what it knows, and the
    // commands are shown disabled at once (the state drawn again without this page's session)
    umbra.lostAt = umbra.lostAt || performance.now();
    const s = Math.round((performance.now() - umbra.lostAt) / 1000);
    umbra.emit("connection", !umbra.silentS || s < umbra.silentS ? "disconnected: reconnecting" :
      `no answer from the run for ${s} s: it ended or failed; reconnecting`);
    if (hadSession && umbra.state) umbra.emit("state", umbra.state);
    setTimeout(umbra.connect, 1000);
  };
  socket.onmessage = (ev) => {
    umbra.heardAt = performance.now();
    if (typeof ev.data !== "string") { umbra.emit("frame", ev.data); return; }
    const m = JSON.parse(ev.data);
    if (m.type === "welcome") {
      umbra.session = m.session; umbra.name = m.name; umbra.silentS = m.silent_s;
      umbra.send("hello", { name: m.name });
    }
    else if (m.type === "notice") umbra.emit("notice", m);
    else if (m.type === "state") {
      // the run's end, as soon as it is said (the first thing a page reconnecting after it hears)
      const end = m.phase === "ended" && !umbra.ended;
      umbra.state = m; umbra.ended = umbra.ended || end;
      umbra.emit("state", m);
      if (end) umbra.emit("ended", m);
      seen(m.version);
    }
  };
};
setInterval(() => {  // a silent socket is dropped (its close opens another)
  if (socket && socket.readyState === 1 && !umbra.ended && umbra.silentS &&
      performance.now() - umbra.heardAt > umbra.silentS * 1000) socket.close();
}, 1000);
