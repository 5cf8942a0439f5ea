// The motion-server live page: session and login, the model's tables (axes, groups,
// instructions) kept live from the status messages, the operator's commands and the
// admin's clock and snapshots. The trend (capture, trigger, cursors, CSV) is in trend.js.
// Protocol: docs/web.md § "Protocol". Everything comes from this origin (CSP 'self').
//
// Test hook: window.msView (see docs/web.md § "Using the page") exposes the session, the
// model, the last status message and the trend capture, so browser tests assert on data.

import { Trend } from "./trend.js";

const $ = (id) => document.getElementById(id);
const ROLE_RANK = { viewer: 0, operator: 1, admin: 2 };
const STATUS_HZ = 20;
const ARM_SECONDS = 10;
const RECONNECT_MS = 1000;
// the axis fields shown, in this order, when the model has them
const AXIS_FIELDS = [
  "AxisState", "PLCopenState", "MotionStatus", "ActualPosition", "CommandPosition",
  "ActualVelocity", "CommandVelocity", "PositionError", "AxisFault", "ServoFault",
  "AxisErrorID",
];
const DEFAULT_CHANNELS = ["ActualPosition", "ActualVelocity"];

const view = {
  session: null,
  model: null,
  status: null,
  statusCount: 0,
  socket: null,
  trend: null,
  lastResult: null,
  reconnects: 0,
  bits: new Map(), // tag -> last value, for the bit-change markers
};
window.msView = view;

// -- HTTP ------------------------------------------------------------------------------
async function api(method, path, body) {
  const headers = { Accept: "application/json" };
  if (body !== undefined) headers["Content-Type"] = "application/json";
  if (method !== "GET" && view.session) headers["X-CSRF-Token"] = view.session.csrf;
  const res = await fetch(path, {
    method,
    headers,
    body: body === undefined ? undefined : JSON.stringify(body),
    credentials: "same-origin",
  });
  let data = null;
  try {
    data = await res.json();
  } catch {
    data = null;
  }
  return { status: res.status, ok: res.ok, data };
}

function say(text, isError = false) {
  const m = $("message");
  m.textContent = text;
  m.classList.toggle("error", isError);
}

function errorText(res) {
  if (res.data && typeof res.data.error === "string") return res.data.error;
  return `HTTP ${res.status}`;
}

// -- session ---------------------------------------------------------------------------
async function start() {
  wireStatic();
  const res = await api("GET", "/api/session");
  if (res.status === 200 && res.data) {
    await enter(res.data);
  } else {
    showLogin(res.status === 401 ? "" : errorText(res));
  }
}

function showLogin(error) {
  $("main").hidden = true;
  $("login").hidden = false;
  $("logout").hidden = true;
  $("login-open").hidden = true;
  $("login-error").textContent = error || "";
  $("who").textContent = "";
  document.body.dataset.role = "";
  $("login-user").focus();
}

async function login(ev) {
  ev.preventDefault();
  const user = $("login-user").value;
  const password = $("login-password").value;
  $("login-password").value = "";
  const res = await api("POST", "/api/login", { user, password });
  if (res.status === 200 && res.data) {
    await enter(res.data);
  } else {
    $("login-error").textContent = errorText(res);
  }
}

async function logout() {
  await api("POST", "/api/logout", {});
  if (view.socket) view.socket.close();
  view.session = null;
  view.socket = null;
  const res = await api("GET", "/api/session");
  if (res.status === 200 && res.data) await enter(res.data);
  else showLogin("");
}

async function enter(session) {
  view.session = session;
  document.body.dataset.role = session.role;
  $("who").textContent = `${session.user ?? "anonymous"} (${session.role})`;
  const anonymous = session.user === null || session.user === undefined;
  $("logout").hidden = anonymous;
  $("login-open").hidden = !anonymous; // anonymous access allowed: a user may still log in
  $("login").hidden = true;
  $("login-error").textContent = "";
  $("main").hidden = false;
  const res = await api("GET", "/api/model");
  if (!res.ok || !res.data) {
    say(`cannot read the model: ${errorText(res)}`, true);
    return;
  }
  view.model = res.data;
  buildTables(view.model);
  if (!view.trend) view.trend = new Trend(view, (channels) => sendTrend(channels));
  view.trend.setModel(view.model);
  const axes = view.model.axes || [];
  const first = axes.length ? axes[0].tags || {} : {};
  const defaults = DEFAULT_CHANNELS.map((f) => first[f]).filter(Boolean);
  view.trend.setChannels(view.trend.channels.length ? view.trend.channels : defaults);
  connect();
}

function canOperate() {
  return view.session !== null && ROLE_RANK[view.session.role] >= ROLE_RANK.operator;
}

// -- the WebSocket ---------------------------------------------------------------------
function connect() {
  if (view.socket) view.socket.close();
  const scheme = location.protocol === "https:" ? "wss:" : "ws:";
  const ws = new WebSocket(`${scheme}//${location.host}/ws`);
  ws.binaryType = "arraybuffer";
  view.socket = ws;
  ws.onopen = () => {
    setLink("up", "online");
    ws.send(JSON.stringify({ type: "status", hz: STATUS_HZ }));
    sendTrend(view.trend.channels);
  };
  ws.onmessage = (ev) => {
    if (typeof ev.data === "string") onText(ev.data);
    else view.trend.onFrame(ev.data);
  };
  ws.onclose = () => {
    if (view.socket !== ws) return;
    setLink("down", "offline");
    setTimeout(() => reconnect(ws), RECONNECT_MS);
  };
}

/** After the socket closed (a restarted front-end, a network blip): is the session still
 * good? Then connect again; if it ended (the server forgot it), ask for a login. */
async function reconnect(ws) {
  if (view.socket !== ws || !view.session) return;
  view.reconnects += 1;
  let res;
  try {
    res = await api("GET", "/api/session");
  } catch {
    setTimeout(() => reconnect(ws), RECONNECT_MS); // the server is not back yet
    return;
  }
  if (view.socket !== ws) return;
  if (res.status === 200 && res.data) {
    if (res.data.user === view.session.user && res.data.role === view.session.role) {
      view.session = res.data; // the CSRF token may be new
      connect();
    } else {
      await enter(res.data);
    }
  } else {
    view.socket = null;
    view.session = null;
    showLogin("the session ended: log in again");
  }
}

function setLink(state, text) {
  const el = $("link-state");
  el.dataset.state = state;
  el.textContent = text;
}

function sendTrend(channels) {
  const ws = view.socket;
  if (ws && ws.readyState === WebSocket.OPEN) {
    ws.send(JSON.stringify({ type: "trend", channels }));
  }
}

function onText(text) {
  let msg;
  try {
    msg = JSON.parse(text);
  } catch {
    return;
  }
  if (msg.type === "status") onStatus(msg);
  else if (msg.type === "hello") view.hello = msg;
  else if (msg.type === "trend-layout") view.trend.onLayout(msg);
  else if (msg.type === "error") say(`server: ${msg.message}`, true);
}

function fmt(value) {
  if (typeof value === "number") {
    if (Number.isInteger(value)) return String(value);
    return value.toFixed(4);
  }
  if (typeof value === "boolean") return value ? "1" : "0";
  if (value === null || value === undefined) return "–";
  return String(value);
}

function onStatus(msg) {
  view.status = msg;
  view.statusCount += 1;
  $("tick").textContent = fmt(msg.tick);
  $("cycle-us").textContent =
    typeof msg.cycle_us === "number" ? msg.cycle_us.toFixed(0) : fmt(msg.cycle_us);
  $("overruns").textContent = fmt(msg.overruns);
  const clock = msg.clock;
  $("clock-mode").textContent =
    clock && typeof clock === "object" ? clock.mode ?? JSON.stringify(clock) : fmt(clock);
  showFrontends(msg.frontends || {});
  const values = msg.values || {};
  for (const [tag, value] of Object.entries(values)) {
    const cells = document.querySelectorAll(`[data-tag="${CSS.escape(tag)}"]`);
    for (const el of cells) show(el, value);
    if (view.bits.has(tag)) {
      const before = view.bits.get(tag);
      const now = Boolean(value);
      if (before !== null && before !== now) view.trend.marker(msg.tick, tag, now);
      view.bits.set(tag, now);
    }
  }
}

function show(el, value) {
  if (el.tagName === "INPUT") {
    if (document.activeElement !== el && !el.dataset.dirty) el.value = fmt(value);
    return;
  }
  if (el.classList.contains("bit")) {
    el.dataset.on = value ? "1" : "0";
    return;
  }
  el.textContent = fmt(value);
}

function showFrontends(frontends) {
  const el = $("frontends");
  el.textContent = "";
  for (const [name, info] of Object.entries(frontends)) {
    const span = document.createElement("span");
    span.className = "health";
    let state = info;
    if (info && typeof info === "object") state = info.state ?? info.status ?? info.alive;
    // a count (restarts) is information; a state says up or down
    const good = typeof state === "number" || [true, "up", "ok", "running"].includes(state);
    span.dataset.ok = good ? "1" : "0";
    span.textContent = `${name}: ${state === true ? "up" : state === false ? "down" : state}`;
    el.appendChild(span);
  }
}

// -- tables ----------------------------------------------------------------------------
function cell(row, text, cls) {
  const td = document.createElement("td");
  if (text !== undefined) td.textContent = text;
  if (cls) td.className = cls;
  row.appendChild(td);
  return td;
}

function header(table, names) {
  const tr = document.createElement("tr");
  for (const n of names) {
    const th = document.createElement("th");
    th.textContent = n;
    tr.appendChild(th);
  }
  const thead = document.createElement("thead");
  thead.appendChild(tr);
  table.appendChild(thead);
}

/** The entries of ``list`` with a name not seen before (a model lists each once). */
function unique(list) {
  const seen = new Set();
  return (list || []).filter((x) => !seen.has(x.name) && seen.add(x.name));
}

function buildTables(model) {
  const ctl = model.controller || {};
  $("controller-name").textContent = ctl.name || "motion-server";
  if (ctl.clock !== undefined) $("clock-mode").textContent = fmt(ctl.clock);
  if (ctl.period_us !== undefined) $("period-us").textContent = fmt(ctl.period_us);
  buildAxes(unique(model.axes));
  buildGroups(unique(model.groups));
  buildInstructions(unique(model.instructions));
  const list = $("channel-list");
  list.textContent = "";
  for (const ch of model.channels || []) {
    const opt = document.createElement("option");
    opt.value = ch;
    list.appendChild(opt);
  }
}

function buildAxes(axes) {
  const table = $("axes-table");
  table.textContent = "";
  const fields = AXIS_FIELDS.filter((f) => axes.some((a) => a.tags && a.tags[f]));
  header(table, ["axis", "type", ...fields]);
  const body = document.createElement("tbody");
  for (const axis of axes) {
    const tr = document.createElement("tr");
    tr.dataset.axis = axis.name;
    cell(tr, axis.name, "name");
    cell(tr, axis.type ?? "");
    for (const f of fields) {
      const td = cell(tr, "–", "num");
      const tag = axis.tags && axis.tags[f];
      if (tag) td.dataset.tag = tag;
    }
    body.appendChild(tr);
  }
  table.appendChild(body);
}

function buildGroups(groups) {
  const table = $("groups-table");
  table.textContent = "";
  const fields = [];
  for (const g of groups) {
    for (const f of Object.keys(g.tags || {})) if (!fields.includes(f)) fields.push(f);
  }
  header(table, ["group", ...fields]);
  const body = document.createElement("tbody");
  for (const g of groups) {
    const tr = document.createElement("tr");
    cell(tr, g.name, "name");
    for (const f of fields) {
      const td = cell(tr, "–", "num");
      const tag = g.tags && g.tags[f];
      if (tag) td.dataset.tag = tag;
    }
    body.appendChild(tr);
  }
  table.appendChild(body);
}

function buildInstructions(instructions) {
  const table = $("instr-table");
  table.textContent = "";
  view.bits.clear();
  header(table, ["instruction", "type", "bits", "operands", ""]);
  const body = document.createElement("tbody");
  for (const ins of instructions) {
    const tr = document.createElement("tr");
    tr.dataset.instruction = ins.name;
    tr.dataset.search = `${ins.name} ${ins.type}`.toLowerCase();
    cell(tr, ins.name, "name");
    cell(tr, `${ins.type} (${ins.family})`);
    const bits = cell(tr, undefined, "bits");
    for (const b of ins.bits || []) {
      const span = document.createElement("span");
      span.className = "bit";
      span.dataset.on = "0";
      span.textContent = b;
      const tag = b.includes(".") ? b : `${ins.name}.${b}`;
      span.dataset.tag = tag;
      view.bits.set(tag, null); // unknown until the first status message
      bits.appendChild(span);
    }
    const ops = cell(tr, undefined, "operands");
    for (const op of ins.operands || []) {
      const label = document.createElement("label");
      label.className = "operand";
      label.textContent = `${op.name} `;
      const input = document.createElement("input");
      input.dataset.tag = op.tag;
      input.dataset.type = op.type;
      input.size = 8;
      input.readOnly = !op.writable || !canOperate();
      input.addEventListener("input", () => {
        input.dataset.dirty = "1";
      });
      label.appendChild(input);
      ops.appendChild(label);
    }
    const act = cell(tr, undefined, "actions op-only");
    const write = button("Write", () => writeOperands(ins, tr));
    write.className = "write";
    const arm = button("Arm", () => armTrigger(ins, tr));
    arm.className = "arm";
    const exec = button("Execute", () => execute(ins, tr));
    exec.className = "execute";
    exec.disabled = true;
    act.append(write, arm, exec);
    body.appendChild(tr);
  }
  table.appendChild(body);
}

function button(text, onClick) {
  const b = document.createElement("button");
  b.type = "button";
  b.textContent = text;
  b.addEventListener("click", onClick);
  return b;
}

function parseOperand(input) {
  const text = input.value.trim();
  const type = input.dataset.type;
  if (type === "BOOL") return text === "1" || text.toLowerCase() === "true";
  const n = Number(text);
  return Number.isFinite(n) ? n : text; // the server judges and answers
}

// -- commands (operator, admin) ----------------------------------------------------------
async function writeOperands(ins, tr) {
  const writes = {};
  for (const input of tr.querySelectorAll("input[data-dirty]")) {
    writes[input.dataset.tag] = parseOperand(input);
  }
  if (!Object.keys(writes).length) {
    say(`${ins.name}: nothing changed to write`);
    return null;
  }
  const res = await api("POST", "/api/write", { writes });
  view.lastResult = res;
  if (!res.ok) {
    say(`${ins.name}: write refused: ${errorText(res)}`, true);
    return res;
  }
  const results = (res.data && res.data.results) || {};
  const bad = Object.entries(results).filter(([, r]) => r !== "ok");
  for (const input of tr.querySelectorAll("input[data-dirty]")) {
    if (results[input.dataset.tag] === "ok") delete input.dataset.dirty;
  }
  if (bad.length) say(bad.map(([t, r]) => `${t}: ${r}`).join("; "), true);
  else say(`${ins.name}: written ${Object.keys(results).join(", ")}`);
  return res;
}

function armTrigger(ins, tr) {
  const exec = tr.querySelector("button.execute");
  exec.disabled = false;
  tr.dataset.armed = "1";
  say(`${ins.name} armed: press Execute within ${ARM_SECONDS} s`);
  clearTimeout(exec._disarm);
  exec._disarm = setTimeout(() => disarm(tr), ARM_SECONDS * 1000);
}

function disarm(tr) {
  const exec = tr.querySelector("button.execute");
  exec.disabled = true;
  delete tr.dataset.armed;
}

async function execute(ins, tr) {
  if (!tr.dataset.armed) return;
  disarm(tr);
  if (tr.querySelector("input[data-dirty]")) {
    const w = await writeOperands(ins, tr);
    if (!w || !w.ok) return;
  }
  const res = await api("POST", "/api/trigger", { instruction: ins.name });
  view.lastResult = res;
  const result = resultText(res);
  if (result === "ok") say(`${ins.name} triggered`);
  else say(`${ins.name}: trigger refused: ${result}`, true);
}

/** "ok", or the one-line reason: an HTTP error or a 200 whose result is not "ok". */
function resultText(res) {
  if (!res.ok) return errorText(res);
  const result = res.data && res.data.result;
  return result === undefined || result === "ok" ? "ok" : String(result);
}

async function clock(action) {
  const body = { action };
  if (action === "step") body.cycles = Number($("step-cycles").value) || 1;
  const res = await api("POST", "/api/clock", body);
  view.lastResult = res;
  const result = resultText(res);
  const tick = res.data && res.data.tick !== undefined ? ` (tick ${res.data.tick})` : "";
  if (result === "ok") say(`clock ${action} done${tick}`);
  else say(`clock ${action} refused: ${result}`, true);
}

async function snapshot(action) {
  const number = Number($("snapshot-number").value);
  const res = await api("POST", "/api/snapshot", { action, number });
  view.lastResult = res;
  const result = resultText(res);
  if (result === "ok") say(`snapshot ${number}: ${action} done`);
  else say(`snapshot ${action} refused: ${result}`, true);
}

function filterInstructions() {
  const q = $("instr-filter").value.trim().toLowerCase();
  for (const tr of $("instr-table").querySelectorAll("tbody tr")) {
    tr.hidden = q !== "" && !tr.dataset.search.includes(q);
  }
}

function wireStatic() {
  $("login-form").addEventListener("submit", login);
  $("logout").addEventListener("click", logout);
  $("login-open").addEventListener("click", () => {
    $("login").hidden = false;
    $("login-user").focus();
  });
  $("clock-step").addEventListener("click", () => clock("step"));
  $("clock-pause").addEventListener("click", () => clock("pause"));
  $("clock-run").addEventListener("click", () => clock("run"));
  $("snapshot-save").addEventListener("click", () => snapshot("save"));
  $("snapshot-restore").addEventListener("click", () => snapshot("restore"));
  $("instr-filter").addEventListener("input", filterInstructions);
}

start();
