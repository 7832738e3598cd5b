// umbra station core: the page's one socket and a small bus the panels subscribe to. Every
// action goes to the server as a checked message; the server decides.
"use strict";
const $ = (id) => document.getElementById(id);
const umbra = (window.umbra = { painted: 0, frame: 0, size: [640, 480], state: null, notices: [],
  session: "", name: "", latencies: [], ended: false, handlers: {} });
let socket = null, seq = 0;
const LOST_S = 5;  // how long [s] without an answer before the page says the run may be gone

umbra.on = (kind, fn) => { (umbra.handlers[kind] = umbra.handlers[kind] || []).push(fn); };
umbra.emit = (kind, data) => { for (const fn of umbra.handlers[kind] || []) fn(data); };
umbra.send = (type, fields = {}) => {
  if (!socket || socket.readyState !== 1 || !umbra.session || umbra.ended) return;
  socket.send(JSON.stringify({ session: umbra.session, seq: ++seq, type, ...fields }));
};
umbra.holds = () => !!(umbra.state && umbra.state.control_session &&
                       umbra.state.control_session === umbra.session);

umbra.connect = () => {
  const token = new URLSearchParams(location.search).get("token");
  const url = `${location.protocol === "https:" ? "wss" : "ws"}://${location.host}/ws` +
              (token ? `?token=${encodeURIComponent(token)}` : "");
  socket = new WebSocket(url);
  socket.binaryType = "arraybuffer";
  socket.onopen = () => { umbra.lostAt = 0; umbra.emit("connection", "connected"); };
  socket.onclose = () => {
    const hadSession = umbra.session !== "";
    umbra.session = ""; seq = 0;
    if (umbra.state && umbra.state.phase === "ended") { umbra.ended = true; umbra.emit("ended", umbra.state); return; }
    // a run that died without saying so: after LOST_S the page says what it knows, and the
    // commands are shown disabled at once (the state drawn again without this page's session)
    umbra.lostAt = umbra.lostAt || performance.now();
    const s = Math.round((performance.now() - umbra.lostAt) / 1000);
    umbra.emit("connection", s < LOST_S ? "disconnected: reconnecting" :
      `no answer from the run for ${s} s: it ended or failed; reconnecting`);
    if (hadSession && umbra.state) umbra.emit("state", umbra.state);
    setTimeout(umbra.connect, 1000);
  };
  socket.onmessage = (ev) => {
    if (typeof ev.data !== "string") { umbra.emit("frame", ev.data); return; }
    const m = JSON.parse(ev.data);
    if (m.type === "welcome") { umbra.session = m.session; umbra.name = m.name; umbra.send("hello", { name: m.name }); }
    else if (m.type === "notice") umbra.emit("notice", m);
    else if (m.type === "state") { umbra.state = m; umbra.emit("state", m); }
  };
};
