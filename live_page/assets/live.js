// The live page: numbers on every websocket message, charts (plotly.js) flushed every 100 ms.
// Read-only: the page sends nothing to the board.
"use strict";
const REGIMES = ["SAFE", "STANDBY_HARVEST", "SENSING", "MAINTENANCE"];
const SLOW_POINTS = 2400;   // points kept per slow series on the page (2 minutes at 20 Hz, as the server)
const MBIT_POINTS = 6000;   // points kept of the current MBIT
const $ = (id) => document.getElementById(id);
const fmt = (v, digits, unit) => (v === null || v === undefined) ? "–" : v.toFixed(digits) + (unit || "");
const ms = (v) => (v === null || v === undefined) ? "–" : (v * 1e3).toFixed(3) + " ms";
const state = { mbit: -1, received: 0, stamps: [], finished: false, regimes: [], boardTime: 0, epsTh: null };
const pending = { slow: { t: [], v: [], soc: [], count: [], rtt: [] }, mbit: { t: [], z: [], zm: [], eps: [] } };

function layout(ytitle, extra) {
  return Object.assign({ margin: { l: 50, r: 40, t: 6, b: 30 }, showlegend: true,
    legend: { orientation: "h", y: 1.15, x: 0, font: { size: 10 } }, font: { size: 10 },
    xaxis: { title: { text: "board time (s)" } }, yaxis: { title: { text: ytitle } } }, extra || {});
}
const config = { displayModeBar: false, responsive: true, staticPlot: true };
const line = (name, extra) => Object.assign({ x: [], y: [], name: name, mode: "lines", type: "scatter" }, extra || {});

function setupCharts() {
  Plotly.newPlot("chart-regime", [line("regime", { line: { shape: "hv", width: 3 } })],
    layout("", { showlegend: false, margin: { l: 120, r: 10, t: 6, b: 30 },
      yaxis: { type: "category", categoryorder: "array", categoryarray: REGIMES, range: [-0.5, 3.5] } }), config);
  Plotly.newPlot("chart-battery", [line("battery (V)"), line("SoC (%)", { yaxis: "y2", line: { dash: "dot" } })],
    layout("V", { margin: { l: 50, r: 64, t: 6, b: 30 },
      yaxis2: { title: { text: "SoC (%)" }, overlaying: "y", side: "right" } }), config);
  Plotly.newPlot("chart-count", [line("fault counter"), line("count_max", { line: { dash: "dash", color: "#c62828" } })],
    layout("count"), config);
  Plotly.newPlot("chart-eps", [line("ε"), line("ε_th", { line: { dash: "dash", color: "#c62828" } })],
    layout("ε (1)"), config);
  Plotly.newPlot("chart-z3", [line("z3 measured"), line("z3 model", { line: { dash: "dot" } })],
    layout("tip (mm)"), config);
  Plotly.newPlot("chart-rtt", [line("round trip p99 (ms)")], layout("ms"), config);
}

function text(id, value) { const el = $(id); if (el.textContent !== value) el.textContent = value; }
function value(id, v) { $(id).dataset.value = (v === null || v === undefined) ? "" : String(v); }

function showNumbers(m) {
  text("source", {rig: "— the rig (shm hil serve)", board: "— the board (shm run)"}[m.source] || "");
  text("title", m.title);
  text("time-label", m.source === "rig" ? "rig time" : "board time");
  text("board-time", fmt(m.board_time_s, 2, " s")); value("board-time", m.board_time_s);
  text("planned", m.planned_s ? "of " + m.planned_s.toFixed(0) + " s" : "");
  text("regime", m.regime || (m.source === "rig" ? "not known to the rig" : "–")); value("regime", m.regime);
  text("regime-since", m.regime_since_s === null ? "–" : m.regime_since_s.toFixed(2) + " s");
  text("v-battery", fmt(m.v_battery_V, 3, " V")); value("v-battery", m.v_battery_V);
  text("soc", m.soc === null ? "–" : (100 * m.soc).toFixed(1) + " %"); value("soc", m.soc);
  text("soc-note", m.soc_note || "");
  text("count", m.monitor_count === null ? "–" : String(m.monitor_count)); value("count", m.monitor_count);
  text("count-max", m.count_max === null ? "–" : String(m.count_max));
  text("latched", m.fault_latched ? "FAULT LATCHED" : "");
  text("maintenance", m.maintenance || "idle");
  text("verdicts", m.verdicts.length ? m.verdicts.join(", ") : "none yet"); value("verdicts", m.verdicts.join(","));
  text("mbit-label", m.mbit_label || "none yet");
  text("eps-max", fmt(m.mbit_max_eps, 3)); value("eps-max", m.mbit_max_eps);
  text("eps-th", fmt(m.eps_th, 3));
  text("mbit-count-max", m.mbit_max_count === null ? "–" : String(m.mbit_max_count));
  value("mbit-count-max", m.mbit_max_count);
  const l = m.link;
  text("exchanges", String(l.exchanges)); value("exchanges", l.exchanges);
  text("misses", String(l.misses)); value("misses", l.misses);
  text("rtt-p50", ms(l.rtt_p50_s)); text("rtt-p99", ms(l.rtt_p99_s));
  text("incidents", String(l.incidents)); value("incidents", l.incidents);
  text("deadline-misses", String(l.deadline_misses));
  text("counters", Object.entries(l.counters).map(([k, v]) => k + " " + v).join(", "));
  text("extra", m.extra.map(([k, v]) => k + ": " + v).join(" · "));
  state.epsTh = m.eps_th; state.countMax = m.count_max; state.boardTime = m.board_time_s;
  state.regimes = m.regimes; state.regime = m.regime;
}

function showStatus(m) {
  const badge = $("status");
  text("status", m.finished ? m.status + " — final state" : m.status); value("status", m.status);
  badge.className = "badge " + (m.finished ? m.status === "finished" ? "finished" : m.status : "");
  if (m.report) { $("report-link").hidden = false; $("report-link").href = m.report; }
  state.finished = m.finished;
}

function addEvents(events) {
  const list = $("events");
  for (const [i, line] of events) {
    const li = document.createElement("li"); li.value = i + 1; li.textContent = line; list.appendChild(li);
  }
  while (list.children.length > 1000) list.removeChild(list.firstChild);
  if (events.length) list.scrollTop = list.scrollHeight;
  text("event-count", "(" + list.children.length + ")");
}

function addChunks(chunks) {
  const s = pending.slow, b = pending.mbit;
  for (const c of chunks) {
    s.t.push(c.t_s); s.v.push(c.v_battery_V); s.soc.push(c.soc === null ? null : 100 * c.soc);
    s.count.push(c.monitor_count); s.rtt.push(c.rtt_p99_s === null ? null : 1e3 * c.rtt_p99_s);
    if (c.mbit_id !== state.mbit && c.mbit_t_s) {   // a new MBIT: its plots start afresh
      state.mbit = c.mbit_id; b.reset = true; b.t = []; b.z = []; b.zm = []; b.eps = [];
    }
    if (c.mbit_t_s) {
      b.t.push(...c.mbit_t_s); b.eps.push(...c.eps);
      b.z.push(...c.z3_meas_m.map((v) => v === null ? null : 1e3 * v));
      b.zm.push(...c.z3_model_m.map((v) => v === null ? null : 1e3 * v));
    }
  }
}

function flushCharts() {
  const s = pending.slow, b = pending.mbit;
  if (s.t.length) {
    Plotly.extendTraces("chart-battery", { x: [s.t, s.t], y: [s.v, s.soc] }, [0, 1], SLOW_POINTS);
    const ts = s.t.slice(), max = ts.map(() => state.countMax);
    Plotly.extendTraces("chart-count", { x: [ts, ts], y: [s.count, max] }, [0, 1], SLOW_POINTS);
    Plotly.extendTraces("chart-rtt", { x: [s.t], y: [s.rtt] }, [0], SLOW_POINTS);
    pending.slow = { t: [], v: [], soc: [], count: [], rtt: [] };
  }
  if (b.reset) {
    Plotly.restyle("chart-eps", { x: [[], []], y: [[], []] }, [0, 1]);
    Plotly.restyle("chart-z3", { x: [[], []], y: [[], []] }, [0, 1]);
  }
  if (b.t.length) {
    const th = b.t.map(() => state.epsTh);
    Plotly.extendTraces("chart-eps", { x: [b.t, b.t], y: [b.eps, th] }, [0, 1], MBIT_POINTS);
    Plotly.extendTraces("chart-z3", { x: [b.t, b.t], y: [b.z, b.zm] }, [0, 1], MBIT_POINTS);
  }
  pending.mbit = { t: [], z: [], zm: [], eps: [] };
  const r = state.regimes;
  if (r.length) {
    const x = r.map((e) => e[0]).concat([state.boardTime]), y = r.map((e) => e[1]).concat([state.regime]);
    Plotly.restyle("chart-regime", { x: [x], y: [y] }, [0]);
  }
}

function onMessage(ev) {
  const m = JSON.parse(ev.data);
  if (m.full) {
    $("events").replaceChildren(); state.mbit = -1;
    pending.slow = { t: [], v: [], soc: [], count: [], rtt: [] }; pending.mbit = { t: [], z: [], zm: [], eps: [] };
    setupCharts();
  }
  showNumbers(m); showStatus(m); addEvents(m.events); addChunks(m.chunks);
  const now = performance.now(); state.received += 1; state.stamps.push(now);
  while (state.stamps.length && state.stamps[0] < now - 1000) state.stamps.shift();
  text("rate", String(state.stamps.length)); value("rate", state.received);
}

function connect() {
  const ws = new WebSocket((location.protocol === "https:" ? "wss://" : "ws://") + location.host + "/ws");
  ws.onmessage = onMessage;
  ws.onclose = () => {
    if (state.finished) { text("status", $("status").textContent.replace(" (server gone)", "") + " (server gone)"); return; }
    text("status", "connection lost — retrying"); $("status").className = "badge lost";
    setTimeout(connect, 2000);
  };
}

setupCharts();
setInterval(flushCharts, 100);
connect();
