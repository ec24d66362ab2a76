// Firelink console: one WebSocket for live data, fetch() for commands.
// The token never appears here: opening the URL the server printed set an
// HttpOnly cookie that the browser sends with every request of this page
// (the server also checks the Origin). Each command is answered with its
// outcome: ok, refused (HTTP 409, with the reason) or failed.
"use strict";

const $ = (id) => document.getElementById(id);
const live = { info: null, state: null, paused: false, frames: 0, lastFps: performance.now(), shown: { id: 0, result: null } };
const MAX_POINTS = 30 * 1000; // 30 s at 1 kHz
let series = null; // per joint: {t, sp, pos, cur}
let selected = 0;
let charts = null;

// Show a command's outcome ({command, result, detail}) as what it is.
function showOutcome(o) {
  const el = $("last-command");
  const result = o.result || "error";
  el.dataset.result = result;
  el.className = "outcome " + result;
  const what = o.command ? o.command + ": " : "";
  const label = result === "refused" ? "REFUSED" : result === "failed" ? "FAILED" : result;
  el.textContent = what + label + (o.detail ? " \u2014 " + o.detail : "");
  live.shown = { id: typeof o.id === "number" ? o.id : live.shown.id, result };
}

async function post(body) {
  let r;
  try {
    r = await fetch("/api/command", {
      method: "POST",
      headers: { "Content-Type": "application/json" },
      body: JSON.stringify(body),
    });
  } catch (e) {
    showOutcome({ command: body.action, result: "error", detail: "the console did not answer: " + e });
    return;
  }
  let o;
  try { o = await r.json(); } catch (e) { o = { detail: "HTTP " + r.status }; }
  if (!o.command) o.command = body.action;
  if (r.status === 403) o.result = "forbidden";
  showOutcome(o);
}

function makeCharts() {
  const width = Math.max(480, $("charts").clientWidth - 40);
  const common = (title, ylabel, names, colours) => ({
    title, width, height: 220,
    scales: { x: { time: false } },
    // Three significant digits on the value axis: a current of a few mA
    // reads 0.002, not 0.
    axes: [{ label: "time, s" }, { label: ylabel, values: (u, ticks) => ticks.map((v) => String(+v.toPrecision(3))) }],
    series: [{ label: "t" }].concat(names.map((n, i) => ({ label: n, stroke: colours[i], width: 1.5 }))),
  });
  const empty = [[], [], []];
  charts = {
    position: new uPlot(common("setpoint and position", "rad or m", ["setpoint", "position"], ["#1f6fd1", "#e8590c"]), empty, $("chart-position")),
    current: new uPlot(common("commanded current", "A", ["current"], ["#2b8a3e"]), [[], []], $("chart-current")),
  };
}

function pushSamples(msg) {
  if (!series) return;
  for (let j = 0; j < series.length; j++) {
    const s = series[j];
    for (let k = 0; k < msg.t.length; k++) {
      s.t.push(msg.t[k]); s.sp.push(msg.setpoint[j][k]); s.pos.push(msg.position[j][k]); s.cur.push(msg.current[j][k]);
    }
    if (s.t.length > MAX_POINTS) {
      const drop = s.t.length - MAX_POINTS;
      s.t.splice(0, drop); s.sp.splice(0, drop); s.pos.splice(0, drop); s.cur.splice(0, drop);
    }
  }
}

function draw() {
  if (charts && series && !live.paused) {
    const s = series[selected];
    const windowS = parseFloat($("window").value);
    const newest = s.t.length ? s.t[s.t.length - 1] : 0;
    let i = s.t.length - 1;
    while (i > 0 && s.t[i - 1] >= newest - windowS) i--;
    i = Math.max(0, i);
    charts.position.setData([s.t.slice(i), s.sp.slice(i), s.pos.slice(i)]);
    charts.current.setData([s.t.slice(i), s.cur.slice(i)]);
    live.frames++;
  }
  const now = performance.now();
  if (now - live.lastFps > 1000) {
    $("fps").textContent = (live.frames * 1000 / (now - live.lastFps)).toFixed(0) + " frames/s";
    document.body.dataset.fps = String(Math.round(live.frames * 1000 / (now - live.lastFps)));
    live.frames = 0; live.lastFps = now;
  }
  requestAnimationFrame(draw);
}

const fmt = (x, d) => (typeof x === "number" ? x.toFixed(d) : "-");
const flag = (on, yes, no) => `<span class="${on ? "on" : "off"}">${on ? yes : no}</span>`;

function showState(st) {
  live.state = st;
  document.body.dataset.state = st.state;
  $("state").textContent = st.state;
  $("state").className = "state " + st.state;
  const info = live.info;
  $("summary").textContent = `${st.boards.length} boards, ${st.joints.length} axes, ${info ? info.port : ""}, t = ${fmt(st.t, 2)} s, I/O ${fmt(st.io_us, 1)} us, errors ${st.errors}`;
  if (st.fault) { $("fault").hidden = false; $("fault").textContent = "FAULT: " + st.fault.text; }
  else { $("fault").hidden = true; $("fault").textContent = ""; }
  // The latest outcome (a command that was still running when its POST
  // answered shows here once done).
  const lc = st.last_command;
  if (lc && (lc.id > live.shown.id || (lc.id === live.shown.id && live.shown.result === "running"))) showOutcome(lc);
  if (st.loop_exit) { $("fault").hidden = false; $("fault").textContent = "ROBOT LOOP ENDED: " + st.loop_exit; }
  const byId = {};
  if (info) for (const b of info.boards) byId[b.id] = b;
  $("boards").tBodies[0].innerHTML = st.boards.map((b) => {
    const amps = st.axes.filter((a) => a.board === b.id);
    const on = b.valid ? amps.filter((a) => a.amp).length : "?";
    const meta = byId[b.id] || {};
    return `<tr data-board="${b.id}"><td>${b.id}</td><td>${meta.firmware ?? "-"}</td><td>${meta.hardware ?? "-"}</td>` +
      `<td>${b.valid ? "yes" : '<span class="bad">no</span>'}</td><td>${flag(b.power, "on", "off")}</td>` +
      `<td>${flag(b.relay, "closed", "open")}</td><td>${b.watchdog_expired ? '<span class="bad">expired</span>' : "ok"}</td>` +
      `<td>${on}/${amps.length}</td><td>0x${(b.status >>> 0).toString(16).padStart(8, "0")}</td></tr>`;
  }).join("");
  const labels = info ? info.joints : [];
  $("joints").tBodies[0].innerHTML = st.joints.map((j, i) =>
    `<tr><td>${labels[i] || i}</td><td>${fmt(j.setpoint, 4)}</td><td>${fmt(j.position, 4)}</td><td>${fmt(j.velocity, 3)}</td><td>${fmt(j.current, 3)}</td></tr>`).join("");
  const answering = {};
  for (const b of st.boards) answering[b.id] = b.valid;
  $("axes").tBodies[0].innerHTML = st.axes.map((a) =>
    `<tr class="${answering[a.board] ? "" : "stale"}" title="${answering[a.board] ? "" : "board not answering: last values read"}"><td>${a.board}</td><td>${a.axis}</td><td>${a.encoder}</td><td>${fmt(a.velocity, 0)}</td><td>${a.pot}</td><td>${fmt(a.current, 3)}</td><td>${flag(a.amp, "on", "off")}</td><td>${a.dac}</td></tr>`).join("");
}

function connect() {
  const ws = new WebSocket(`ws://${location.host}/ws`);
  ws.onopen = () => { $("link").textContent = "live"; $("link").className = "link live"; };
  ws.onclose = () => { $("link").textContent = "offline (retrying)"; $("link").className = "link"; setTimeout(connect, 1000); };
  ws.onmessage = (ev) => {
    const msg = JSON.parse(ev.data);
    if (msg.type === "samples") pushSamples(msg);
    else if (msg.type === "state") showState(msg);
  };
}

async function start() {
  const r = await fetch("/api/info");
  if (!r.ok) {
    $("summary").textContent = "not authorised";
    showOutcome({ result: "forbidden", detail: "open the URL with the token that this run of firelink web printed (it sets this console's cookie)" });
    return;
  }
  live.info = await r.json();
  if (live.info.robot && live.info.robot !== "dvrk") {
    // Snake or MAHRU: their own view (robots.js), the same commands API.
    startRobotView(live.info);
    return;
  }
  series = live.info.joints.map(() => ({ t: [], sp: [], pos: [], cur: [] }));
  $("joint").innerHTML = live.info.joints.map((l, i) => `<option value="${i}">${l}</option>`).join("");
  $("joint").onchange = () => { selected = parseInt($("joint").value, 10); };
  for (const f of live.info.faults) {
    const b = document.createElement("button");
    b.textContent = f; b.dataset.fault = f;
    b.onclick = () => post({ action: "inject", fault: f });
    $("faults").appendChild(b);
  }
  for (const b of document.querySelectorAll("button[data-action]")) {
    b.onclick = () => {
      const body = { action: b.dataset.action };
      if (b.dataset.on) body.on = b.dataset.on === "true";
      post(body);
    };
  }
  $("set-watchdog").onclick = () => post({ action: "watchdog", watchdog_ms: parseFloat($("watchdog-ms").value) });
  $("pause").onclick = () => { live.paused = !live.paused; $("pause").textContent = live.paused ? "Resume" : "Pause"; };
  $("csv").onclick = (e) => {
    e.preventDefault();
    location.href = `/api/csv?seconds=${encodeURIComponent($("csv-seconds").value)}`;
  };
  $("fig11-button").onclick = () => {
    $("fig11").hidden = false;
    $("fig11").src = `/api/fig11.png?t=${Date.now()}`;
  };
  makeCharts();
  connect();
  requestAnimationFrame(draw);
}

start();
