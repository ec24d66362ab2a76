// Firelink console: the views of the robots other than the dVRK (seed
// 001's Snake system, seed 002's MAHRU humanoid). The state is polled from
// /api/state (the same cookie and checks as the dVRK's); commands go
// through post() of app.js, which shows each one's outcome.
"use strict";

const robotView = { info: null, axis: 0, module: 0, polling: false, charts: {}, history: {} };
const HISTORY_S = 30;

// A strip chart of two series (uPlot, as the dVRK's) in `el`.
function robotChart(el, title, unit, names, colours) {
  const width = Math.max(420, el.parentElement.clientWidth - 40);
  return new uPlot({
    title, width, height: 200,
    // A flat line gets a narrow band around it, not uPlot's 0..100.
    scales: { x: { time: false }, y: { range: (u, lo, hi) => {
      const pad = Math.max((hi - lo) * 0.05, Math.abs(hi) * 0.01, 1e-3);
      return [lo - pad, hi + pad];
    } } },
    axes: [{ label: "time, s" }, { label: unit, values: (u, ticks) => ticks.map((v) => String(+v.toPrecision(3))) }],
    series: [{ label: "t" }].concat(names.map((n, i) => ({ label: n, stroke: colours[i], width: 1.5 }))),
  }, [[], [], []], el);
}

// Add one point to the history `name` and redraw its chart (the last
// HISTORY_S seconds; a clock that went back starts the history again).
function chartPoint(name, t, a, b) {
  let h = robotView.history[name];
  if (!h || (h.t.length && t < h.t[h.t.length - 1])) h = robotView.history[name] = { t: [], a: [], b: [] };
  if (h.t.length && t === h.t[h.t.length - 1]) return;
  h.t.push(t); h.a.push(a); h.b.push(b);
  while (h.t.length && h.t[0] < t - HISTORY_S) { h.t.shift(); h.a.shift(); h.b.shift(); }
  robotView.charts[name].setData([h.t.slice(), h.a.slice(), h.b.slice()]);
}

function startRobotView(info) {
  robotView.info = info;
  document.body.dataset.robot = info.robot;
  document.title = `Firelink console: ${info.robot}`;
  $("dvrk-view").hidden = true;
  const view = $(`${info.robot}-view`);
  view.hidden = false;
  // The outcome line belongs to this view's controls.
  view.querySelector(".command-slot").appendChild($("last-command"));
  for (const b of view.querySelectorAll("button[data-robot-action]")) {
    b.onclick = () => post({ action: b.dataset.robotAction });
  }
  if (info.robot === "snake") setUpSnake(info);
  else setUpMahru(info);
  poll();
}

async function poll() {
  if (robotView.polling) return;
  robotView.polling = true;
  for (;;) {
    try {
      const r = await fetch("/api/state");
      if (!r.ok) throw new Error("HTTP " + r.status);
      const st = await r.json();
      $("link").textContent = "live"; $("link").className = "link live";
      if (st.state !== undefined) showRobotState(st);
    } catch (e) {
      $("link").textContent = "offline (retrying)"; $("link").className = "link";
    }
    await new Promise((done) => setTimeout(done, 100));
  }
}

function showRobotState(st) {
  live.state = st;
  document.body.dataset.state = st.state;
  $("state").textContent = st.state;
  $("state").className = "state " + (st.state === "enabled" ? "active" : st.state);
  const lc = st.last_command;
  if (lc && (lc.id > live.shown.id || (lc.id === live.shown.id && live.shown.result === "running"))) showOutcome(lc);
  const fault = document.querySelector(`#${robotView.info.robot}-view .robot-fault`);
  const text = st.loop_exit ? "ROBOT LOOP ENDED: " + st.loop_exit : st.fault ? "FAULT: " + st.fault.text : "";
  fault.hidden = !text; fault.textContent = text;
  if (robotView.info.robot === "snake") showSnake(st);
  else showMahru(st);
}

// ---- Snake ----

function setUpSnake(info) {
  const axis = $("snake-axis");
  axis.innerHTML = info.joints.map((l, i) => `<option value="${i}">${i}: ${l}</option>`).join("");
  const select = (i) => {
    robotView.axis = i;
    axis.value = String(i);
    delete robotView.history.axis;
    $("snake-chart-axis").textContent = `${i}: ${info.joints[i]}`;
  };
  axis.onchange = () => select(parseInt(axis.value, 10));
  robotView.charts.axis = robotChart($("snake-chart"), "", "rad or m", ["setpoint", "position"], ["#1f6fd1", "#e8590c"]);
  select(0);
  for (const f of info.faults) {
    const b = document.createElement("button");
    b.textContent = f; b.dataset.fault = f;
    b.onclick = () => post({ action: "inject", fault: f });
    $("snake-faults").appendChild(b);
  }
  const a = () => robotView.axis;
  const num = (id) => parseFloat($(id).value);
  $("snake-torque").onclick = () => post({ action: "mode", axis: a(), speed: false });
  $("snake-speed").onclick = () => post({ action: "mode", axis: a(), speed: true });
  $("snake-set-wiper").onclick = () => post({ action: "wiper", axis: a(), wiper: num("snake-wiper") });
  $("snake-eeprom-read").onclick = () => post({ action: "eeprom_read", axis: a(), word: num("snake-word"), float: $("snake-float").checked });
  $("snake-eeprom-write").onclick = () => post({ action: "eeprom_write", axis: a(), word: num("snake-word"), value: num("snake-value"), float: $("snake-float").checked });
  $("snake-protect-on").onclick = () => post({ action: "write_protect", axis: a(), on: true });
  $("snake-protect-off").onclick = () => post({ action: "write_protect", axis: a(), on: false });
  $("snake-move").onclick = () => post({ action: "move", axis: a(), position: num("snake-position") });
  $("snake-jog-minus").onclick = () => post({ action: "jog", axis: a(), delta: -num("snake-jog") });
  $("snake-jog-plus").onclick = () => post({ action: "jog", axis: a(), delta: num("snake-jog") });
  $("snake-axes").tBodies[0].onclick = (e) => {
    const row = e.target.closest("tr");
    if (row) select(parseInt(row.dataset.axis, 10));
  };
}

function showSnake(st) {
  const info = robotView.info;
  const amps = st.axes.filter((x) => x.amp).length;
  $("summary").textContent = `Snake: ${st.nodes.length} nodes, ${st.axes.length} axes, ${info.port}, t = ${fmt(st.t, 2)} s, I/O ${fmt(st.io_us, 1)} us, errors ${st.errors}`;
  const expired = st.nodes.filter((n) => n.watchdog_expired).map((n) => n.id);
  const silent = st.nodes.filter((n) => !n.valid).map((n) => n.id);
  const faults = st.axes.map((x, i) => (x.fault ? i : -1)).filter((i) => i >= 0);
  $("snake-safety").innerHTML = `safety: ${amps} of ${st.axes.length} amplifiers on; homed ${flag(st.homed, "yes", "no")}; ` +
    `watchdog expired: ${expired.length ? `<span class="bad">nodes ${expired.join(", ")}</span>` : "none"}; ` +
    `not answering: ${silent.length ? `<span class="bad">nodes ${silent.join(", ")}</span>` : "none"}; ` +
    `channel faults: ${faults.length ? `<span class="bad">axes ${faults.join(", ")}</span>` : "none"}`;
  const c = st.axes[robotView.axis];
  if (c) chartPoint("axis", st.t, c.setpoint, c.position);
  if (c) $("snake-where").textContent = `(node ${c.node}, channel ${c.channel}: wiper ${c.wiper}, gain ${fmt(c.gain, 3)}, ${c.speed_mode ? "speed" : "torque"} mode, EEPROM ${c.write_protect ? "write-protected" : "writable"})`;
  $("snake-nodes").tBodies[0].innerHTML = st.nodes.map((n) =>
    `<tr data-node="${n.id}"><td>${n.id}</td><td>${n.valid ? "yes" : '<span class="bad">no</span>'}</td>` +
    `<td>${n.watchdog_expired ? '<span class="bad">expired</span>' : "ok"}</td><td>${n.amps.toString(2).split("").filter((b) => b === "1").length}/7</td></tr>`).join("");
  $("snake-axes").tBodies[0].innerHTML = st.axes.map((x, i) =>
    `<tr data-axis="${i}" class="${i === robotView.axis ? "selected" : ""}"><td>${i}: ${info.joints[i]}</td><td>${x.node}</td><td>${x.channel}</td>` +
    `<td>${fmt(x.setpoint, 4)}</td><td>${fmt(x.position, 4)}</td><td>${fmt(x.velocity, 3)}</td><td>${fmt(x.current_cmd, 3)}</td><td>${fmt(x.current, 3)}</td>` +
    `<td>${x.encoder}</td><td>${x.pot}</td><td>${flag(x.amp, "on", "off")}</td><td>${x.fault ? '<span class="bad">FAULT</span>' : "-"}</td>` +
    `<td>${x.wiper}</td><td>${fmt(x.gain, 3)}</td><td class="mode">${x.speed_mode ? "speed" : "torque"}</td><td class="protect">${x.write_protect ? "protected" : "writable"}</td></tr>`).join("");
}

// ---- MAHRU ----

function setUpMahru(info) {
  const motors = info.modules.filter((m) => m.kind === "motor");
  const select = $("mahru-module");
  select.innerHTML = motors.map((m) => `<option value="${m.mod_id}">${m.mod_id}: ${m.name}</option>`).join("");
  robotView.module = motors.length ? motors[0].mod_id : 0;
  select.onchange = () => { robotView.module = parseInt(select.value, 10); delete robotView.history.module; };
  robotView.charts.module = robotChart($("mahru-chart"), "", "rad", ["target", "position"], ["#1f6fd1", "#e8590c"]);
  robotView.charts.budget = robotChart($("mahru-budget-chart"), "", "us", ["work", "period"], ["#2b8a3e", "#c0262d"]);
}

function showMahru(st) {
  const info = robotView.info;
  const b = st.budget;
  $("summary").textContent = `MAHRU: ${st.modules.length} modules, ${info.rtos}, ${info.port}, t = ${fmt(st.t, 2)} s, period ${fmt(b.period_us, 0)} us, missed ${st.missed}`;
  const g = st.gait;
  $("mahru-walking").textContent = g.walking ? "walking" : "holding";
  $("mahru-walking").className = g.walking ? "on" : "off";
  $("mahru-phase").value = g.phase;
  $("mahru-phase-text").textContent = `phase ${fmt(g.phase, 2)} of a ${fmt(info.stride_s, 2)} s stride, gait time ${fmt(g.time_s, 2)} s`;
  const row = (name, us) => {
    const share = b.period_us > 0 ? us / b.period_us : 0;
    const width = Math.min(200, Math.round(200 * share));
    return `<tr><td>${name}</td><td>${fmt(us, 1)}</td><td><span class="bar${share > 1 ? " over" : ""}" style="width:${width}px"></span> ${fmt(100 * share, 1)} %</td></tr>`;
  };
  $("mahru-budget").tBodies[0].innerHTML = row("read all, t(Te)", b.read_us) + row("compute, t(Tf)", b.compute_us) +
    row("QWRITE, t(Tg)", b.write_us) + row("whole work", b.busy_us) + row("largest work", b.busy_max_us);
  $("mahru-budget-summary").textContent = `used ${fmt(b.busy_us, 1)} of ${fmt(b.period_us, 0)} us available; ${b.periods} periods, ${b.overruns} overruns`;
  const byId = {};
  for (const m of info.modules) byId[m.mod_id] = m;
  const chosen = st.modules.find((m) => m.mod_id === robotView.module);
  if (chosen && chosen.valid) chartPoint("module", st.t, chosen.target, chosen.position);
  if (b.periods > 0) chartPoint("budget", st.t, b.busy_us, b.period_us);
  const motors = st.modules.filter((m) => (byId[m.mod_id] || {}).kind === "motor");
  const sensors = st.modules.filter((m) => (byId[m.mod_id] || {}).kind === "force_torque");
  $("mahru-modules").tBodies[0].innerHTML = st.modules.map((m) => {
    const meta = byId[m.mod_id] || {};
    const motor = meta.kind === "motor";
    const v = (x, d) => (motor && m.valid ? fmt(x, d) : "-");
    return `<tr data-mod="${m.mod_id}"><td>${m.mod_id}</td><td>${meta.name ?? "-"}</td><td>${meta.chain ?? "-"}</td><td>${m.state}</td>` +
      `<td>${v(m.position, 4)}</td><td>${v(m.target, 4)}</td><td>${v(m.velocity, 3)}</td><td>${v(m.current, 3)}</td><td>${v(m.torque, 3)}</td><td>${fmt(m.read_us, 1)}</td></tr>`;
  }).join("");
  $("mahru-ft").tBodies[0].innerHTML = sensors.map((m) =>
    `<tr data-mod="${m.mod_id}"><td>${(byId[m.mod_id] || {}).name ?? m.mod_id}</td>` + m.wrench.map((x) => `<td>${m.valid ? fmt(x, 2) : "-"}</td>`).join("") + "</tr>").join("");
  document.body.dataset.motors = String(motors.length);
}
