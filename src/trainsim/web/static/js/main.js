// The page: four views (train, track, run, live driving) over the JSON API and the drive WebSocket.
import { del, get, post, put, upload } from "./api.js";
import { SpecEditor } from "./editor.js";
import {
  clock, DrivePlot, plotCouplerHeatmap, plotEnergyTime, plotOperationDelays, plotOperationHeadways, plotProfile, plotRuns,
  plotTrainCurves, plotTrainGraph,
} from "./plots.js";

const $ = (sel) => document.querySelector(sel);
const h = (tag, attrs = {}, ...children) => {
  const node = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (k === "class") node.className = v;
    else if (k === "text") node.textContent = v;
    else if (k.startsWith("on")) node.addEventListener(k.slice(2), v);
    else if (v !== undefined && v !== null && v !== false) node.setAttribute(k, v === true ? "" : v);
  }
  for (const c of children) if (c !== null && c !== undefined) node.append(c);
  return node;
};
const fmt = (x, digits = 1) => {
  if (x === null || x === undefined || Number.isNaN(Number(x))) return "–";
  const text = Number(x).toFixed(digits);
  return Number(text) === 0 ? Number(0).toFixed(digits) : text; // no "-0.0"
};

const state = {
  tab: "train",
  examples: [],
  strategies: [],
  settings: { max_step_m: 20, braking_fraction: 1 },
  train: null,
  route: null,
  runs: [],
  runA: null,
  runB: null,
  cache: new Map(),
  runsDirty: true,
};

// ------------------------------------------------------------ helpers
let busyCount = 0;
async function busy(promise) {
  busyCount += 1;
  $("#busy").hidden = false;
  try {
    return await promise;
  } finally {
    busyCount -= 1;
    $("#busy").hidden = busyCount === 0;
  }
}

function showErrors(box, data, unplaced) {
  box.replaceChildren();
  if (!data) return;
  box.append(h("div", { class: "message", text: data.message || "error" }));
  const items = (unplaced || []).filter((d) => d.msg);
  if (items.length) box.append(h("ul", {}, ...items.map((d) => h("li", { text: `${d.field || "(file)"}: ${d.msg}` }))));
}

function setStatus(node, text, kind) {
  node.textContent = text;
  node.className = `status ${kind || ""}`;
}

function fillFigures(table, figures, labels) {
  table.replaceChildren();
  for (const [key, label, unit, digits] of labels) {
    const v = figures[key];
    if (v === undefined || v === null) continue;
    const shown = typeof v === "number" ? fmt(v, digits) : typeof v === "boolean" ? (v ? "yes" : "no") : v;
    table.append(h("tr", {}, h("td", { text: label }), h("td", { class: "v", text: `${shown}${unit ? ` ${unit}` : ""}` })));
  }
}

function fillNotes(list, notes, warnings) {
  list.replaceChildren(...(warnings || []).map((w) => h("li", { class: "warning", text: w })),
    ...(notes || []).map((n) => h("li", { text: n })));
}

function updateHeader() {
  $("#current-train").textContent = state.train ? state.train.name : "none";
  $("#current-route").textContent = state.route ? state.route.name : "none";
}

function switchTab(tab) {
  state.tab = tab;
  for (const b of document.querySelectorAll("#tabs button")) b.classList.toggle("active", b.dataset.tab === tab);
  for (const s of document.querySelectorAll("section.tab")) s.hidden = s.id !== `tab-${tab}`;
  // Plotly sizes a figure from its container: draw (or resize) once it is visible
  if (tab === "run") renderRuns();
  if (tab === "train" && state.train) plotTrainCurves($("#train-plot"), state.train.curves, state.train.name);
  if (tab === "track" && state.route) plotProfile($("#route-plot"), state.route.profile);
  window.dispatchEvent(new Event("resize"));
}

// ------------------------------------------------------------ train and track pages
class SpecPage {
  constructor(kind, opts) {
    this.kind = kind; // "train" | "route"
    this.opts = opts;
    this.editor = null;
    this.seq = 0;
    this.timer = null;
    this.status = $(`#${kind}-status`);
    this.errors = $(`#${kind}-errors`);
  }

  async init() {
    const schema = await get(`/api/schema/${this.kind}`);
    this.editor = new SpecEditor($(`#${this.kind}-editor`), schema.data, () => this.edited());
    $(`#${this.kind}-file`).addEventListener("change", (ev) => this.open(ev.target.files[0], ev.target));
    $(`#${this.kind}-example`).addEventListener("click", () => this.example());
    const current = await get(`/api/${this.kind}`);
    if (current.ok) this.loaded(current.data, "");
  }

  loaded(payload, message) {
    state[this.kind] = payload;
    this.editor.setData(structuredClone(payload.spec));
    this.show(payload);
    showErrors(this.errors, null);
    setStatus(this.status, message || `${payload.source}`, "ok");
  }

  show(payload) {
    state[this.kind] = payload;
    this.opts.render(payload);
    fillNotes($(`#${this.kind}-notes`), payload.notes, payload.warnings);
    updateHeader();
  }

  edited() {
    clearTimeout(this.timer);
    setStatus(this.status, "checking…", "");
    this.timer = setTimeout(() => this.save(), 250);
  }

  async save() {
    const seq = ++this.seq;
    const answer = await busy(put(`/api/${this.kind}`, this.editor.data));
    if (seq !== this.seq) return; // a newer edit is on its way
    if (answer.ok) {
      this.editor.clearErrors();
      showErrors(this.errors, null);
      this.show(answer.data);
      setStatus(this.status, "✓ valid — saved in this session", "ok");
      changedInputs();
    } else {
      const unplaced = this.editor.showErrors(answer.data.detail);
      showErrors(this.errors, answer.data, unplaced);
      const n = (answer.data.detail || []).length || 1;
      setStatus(this.status, `✗ ${n} problem${n > 1 ? "s" : ""} — the last valid ${this.kind === "route" ? "track" : "train"} is kept`, "bad");
    }
  }

  async open(file, input) {
    if (!file) return;
    const answer = await busy(upload(`/api/${this.kind}/upload`, file));
    input.value = "";
    if (answer.ok) {
      this.loaded(answer.data, `opened ${file.name}`);
      changedInputs();
    } else {
      showErrors(this.errors, answer.data, answer.data.detail);
      setStatus(this.status, `✗ could not open ${file.name}`, "bad");
    }
  }

  async example() {
    const name = $("#example-select").value;
    const answer = await busy(post(`/api/${this.kind}/example/${encodeURIComponent(name)}`));
    if (answer.ok) {
      this.loaded(answer.data, `example ${name}`);
      if (this.kind === "route") await refreshSession();
      changedInputs();
    } else showErrors(this.errors, answer.data);
  }
}

const TRAIN_FIGURES = [
  ["mass_t", "mass", "t", 1], ["inertial_mass_t", "inertial mass (ρ m)", "t", 1], ["length_m", "length", "m", 1],
  ["max_speed_kmh", "max speed", "km/h", 1], ["traction_at_0_kn", "traction at 0 km/h", "kN", 1],
  ["traction_at_max_speed_kn", "traction at max speed", "kN", 1], ["max_traction_power_kw", "max traction power", "kW", 0],
  ["resistance_at_max_speed_kn", "resistance at max speed", "kN", 2], ["braking", "braking", "", 0],
  ["regenerative_braking", "regenerative braking", "", 0], ["line_voltage_v", "line voltage", "V", 0],
];
const ROUTE_FIGURES = [
  ["length_m", "length", "m", 2], ["stations", "stations", "", 0], ["stops", "stops", "", 0],
  ["speed_limit_sections", "speed-limit sections", "", 0], ["gradient_sections", "gradient sections", "", 0],
  ["curves", "curves", "", 0], ["tunnels", "tunnels", "", 0],
];

const trainPage = new SpecPage("train", {
  render: (p) => {
    if (state.tab === "train") plotTrainCurves($("#train-plot"), p.curves, p.name);
    fillFigures($("#train-figures"), p.figures, TRAIN_FIGURES);
  },
});
const routePage = new SpecPage("route", {
  render: (p) => {
    if (state.tab === "track") plotProfile($("#route-plot"), p.profile);
    fillFigures($("#route-figures"), p.figures, ROUTE_FIGURES);
  },
});

async function refreshSession() {
  const s = await get("/api/session");
  if (!s.ok) return;
  state.settings = s.data.settings;
  state.runs = s.data.runs;
  $("#run-step").value = state.settings.max_step_m;
  $("#run-braking").value = state.settings.braking_fraction;
}

// ------------------------------------------------------------ runs
const SUMMARY_ROWS = [
  ["status", "status", "", null],
  ["running_time_s", "running time", "s", 1],
  ["dwell_s", "dwell", "s", 1],
  ["total_time_s", "total time", "s", 1],
  ["distance_m", "distance", "m", 1],
  ["max_speed_kmh", "max speed", "km/h", 1],
  ["average_running_speed_kmh", "average running speed", "km/h", 2],
  ["average_speed_kmh", "average speed", "km/h", 2],
  ["peak_current_a", "peak line current", "A", 0],
  ["energy_kwh.traction", "traction energy (wheel)", "kWh", 2],
  ["energy_kwh.braking", "braking energy (wheel)", "kWh", 2],
  ["energy_kwh.regenerated", "regenerated (to line)", "kWh", 2],
  ["energy_kwh.auxiliary", "auxiliaries", "kWh", 2],
  ["energy_kwh.net", "net energy from line", "kWh", 2],
];
const pick = (obj, key) => key.split(".").reduce((o, k) => (o ? o[k] : undefined), obj);

function changedInputs() {
  state.runsDirty = true;
  if ($("#run-auto").checked && state.train && state.route) autoRun();
}

let autoTimer = null;
// what the last automatic run ran (train, track, request): an edit that changes nothing runs nothing
let lastAutoKey = null;
let lastAutoRun = null;
function autoRun() {
  clearTimeout(autoTimer);
  autoTimer = setTimeout(async () => {
    const key = JSON.stringify([state.train && state.train.spec, state.route && state.route.spec, runRequest("auto")]);
    if (key === lastAutoKey) return;
    // the baseline (B) is the run shown before this series of edits; it stays while edits follow
    const baseline = state.runB && state.runB !== lastAutoRun ? state.runB : state.runA;
    const run = await doRun("auto");
    if (!run) return;
    lastAutoKey = key;
    if (lastAutoRun && lastAutoRun !== baseline && lastAutoRun !== run.id) {
      await del(`/api/runs/${lastAutoRun}`); // the previous automatic run: replaced, not piled up
      state.cache.delete(lastAutoRun);
    }
    lastAutoRun = run.id;
    state.runA = run.id;
    state.runB = baseline && baseline !== run.id ? baseline : null;
    await refreshRuns();
  }, 200);
}

function runRequest(labelMode) {
  const strategy = $("#run-strategy").value || "fastest";
  const params = {};
  for (const input of document.querySelectorAll("#run-params [data-param]")) {
    if (input.value.trim() === "") continue;
    const num = (x) => (Number.isFinite(Number(x)) ? Number(x) : x);
    if (input.dataset.points) {
      // "position: earliest-latest @ lowest-highest km/h" per point (either window may be left out),
      // points separated by ";" (an unreadable entry is sent as it is, and the server says what is
      // wrong with it)
      params.timing_points = input.value.split(";").map((x) => x.trim()).filter((x) => x !== "").map((x) => {
        const m = x.match(
          /^([\d.]+)\s*m?\s*:\s*(?:([\d.]*)\s*-\s*([\d.]*)\s*s?)?\s*(?:@\s*([\d.]*)\s*-\s*([\d.]*)\s*(?:km\/h)?)?$/);
        if (!m || (m[2] === undefined && m[4] === undefined)) return x;
        const p = { position_m: Number(m[1]) };
        for (const [k, key] of [[2, "earliest_s"], [3, "latest_s"], [4, "min_speed_kmh"], [5, "max_speed_kmh"]]) {
          if (m[k] !== undefined && m[k] !== "") p[key] = Number(m[k]);
        }
        return p;
      });
      continue;
    }
    params[input.dataset.param] = input.dataset.list
      ? input.value.split(/[,;\s]+/).filter((x) => x !== "").map(num)
      : num(input.value.trim());
  }
  const settings = {};
  for (const [id, key] of [["#run-step", "max_step_m"], ["#run-braking", "braking_fraction"]]) {
    const raw = $(id).value.trim();
    if (raw !== "") settings[key] = Number.isFinite(Number(raw)) ? Number(raw) : raw;
  }
  const label = $("#run-label").value.trim();
  return { strategy, params, settings, label: label && labelMode !== "auto" ? label : undefined };
}

async function doRun(labelMode) {
  const errors = $("#run-errors");
  for (const n of document.querySelectorAll(".run-form .invalid")) n.classList.remove("invalid");
  const answer = await busy(post("/api/runs", runRequest(labelMode)));
  if (!answer.ok) {
    showErrors(errors, answer.data, answer.data.detail);
    for (const d of answer.data.detail || []) {
      const input = document.querySelector(`.run-form [data-path="${d.field}"]`);
      if (input) input.classList.add("invalid");
    }
    return null;
  }
  showErrors(errors, null);
  state.cache.set(answer.data.id, answer.data);
  state.runA = answer.data.id;
  await refreshRuns();
  return answer.data;
}

async function refreshRuns() {
  const list = await get("/api/runs");
  if (list.ok) state.runs = list.data;
  const ids = new Set(state.runs.map((r) => r.id));
  if (!ids.has(state.runA)) state.runA = state.runs.length ? state.runs[state.runs.length - 1].id : null;
  if (!ids.has(state.runB) || state.runB === state.runA) state.runB = null;
  state.runsDirty = true;
  renderRuns();
}

async function runPayload(id) {
  if (!state.cache.has(id)) {
    const answer = await get(`/api/runs/${id}`);
    if (!answer.ok) return null;
    state.cache.set(id, answer.data);
  }
  return state.cache.get(id);
}

function renderRunsTable() {
  const table = $("#runs-table");
  table.replaceChildren(h("tr", {}, ...["A", "B", "run", "strategy", "train", "line", "status", "running time [s]",
    "total time [s]", "net energy [kWh]", "download", ""].map((t) => h("th", { text: t }))));
  for (const r of [...state.runs].reverse()) {
    const radio = (which) => {
      const input = h("input", { type: "radio", name: `run-${which}`, value: r.id, "aria-label": `${which} ${r.label}` });
      input.checked = (which === "a" ? state.runA : state.runB) === r.id;
      input.addEventListener("change", () => {
        if (which === "a") state.runA = r.id;
        else state.runB = r.id;
        if (state.runA === state.runB) state.runB = null;
        state.runsDirty = true;
        renderRuns();
      });
      return input;
    };
    const cls = r.id === state.runA ? "a" : r.id === state.runB ? "b" : "";
    table.append(h("tr", { class: cls, "data-run": r.id },
      h("td", {}, radio("a")), h("td", {}, radio("b")), h("td", { text: r.label }), h("td", { text: r.strategy }),
      h("td", { text: r.train }), h("td", { text: r.route }), h("td", { text: r.status }), h("td", { class: "n", text: fmt(r.running_time_s, 1) }),
      h("td", { class: "n", text: fmt(r.total_time_s, 1) }), h("td", { class: "n", text: fmt(r.energy_net_kwh, 2) }),
      h("td", {}, h("a", { href: `/api/runs/${r.id}/trace.csv`, download: "", text: "trace CSV" }), " ",
        h("a", { href: `/api/runs/${r.id}/summary.json`, download: "", text: "summary JSON" })),
      h("td", {}, h("button", { type: "button", class: "icon", title: "forget this run", text: "×", onclick: async () => {
        await del(`/api/runs/${r.id}`);
        state.cache.delete(r.id);
        await refreshRuns();
      } }))));
  }
  if (state.runB) {
    table.append(h("tr", {}, h("td", { colspan: 12 }, h("button", { type: "button", text: "stop comparing (clear B)",
      onclick: () => { state.runB = null; state.runsDirty = true; renderRuns(); } }))));
  }
}

function renderSummary(a, b) {
  const table = $("#summary-table");
  const head = h("tr", {}, h("th", { text: "summary" }), h("th", { class: "a", text: a.label }));
  if (b) head.append(h("th", { class: "b", text: b.label }), h("th", { text: "B − A" }));
  table.replaceChildren(head);
  for (const [key, label, unit, digits] of SUMMARY_ROWS) {
    const va = pick(a.summary, key);
    const row = h("tr", { "data-key": key }, h("td", { text: unit ? `${label} [${unit}]` : label }),
      h("td", { class: "a", text: digits === null ? String(va) : fmt(va, digits) }));
    if (b) {
      const vb = pick(b.summary, key);
      row.append(h("td", { class: "b", text: digits === null ? String(vb) : fmt(vb, digits) }),
        h("td", { class: "d", text: digits === null || va === null || vb === null ? "" : fmt(vb - va, digits) }));
    }
    table.append(row);
  }
  const sections = $("#sections-table");
  const cols = [["from", "from"], ["to", "to"], ["distance_m", "distance [m]", 1], ["running_time_s", "running [s]", 1],
    ["dwell_s", "dwell [s]", 0], ["max_speed_kmh", "max [km/h]", 1], ["average_speed_kmh", "avg [km/h]", 1],
    ["energy_kwh.traction", "traction [kWh]", 2], ["energy_kwh.net", "net [kWh]", 2], ["peak_current_a", "peak current [A]", 0]];
  sections.replaceChildren(h("tr", {}, h("th", { colspan: cols.length, text: `sections — ${a.label}` })),
    h("tr", {}, ...cols.map(([, t]) => h("th", { text: t }))));
  for (const s of a.summary.sections) {
    sections.append(h("tr", {}, ...cols.map(([k, , d]) => h("td", { class: d === undefined ? "" : "n", text: d === undefined ? pick(s, k) : fmt(pick(s, k), d) }))));
  }
  const warnings = [...a.summary.warnings.map((w) => `${a.label}: ${w}`), ...(b ? b.summary.warnings.map((w) => `${b.label}: ${w}`) : [])];
  $("#run-warnings").replaceChildren(...warnings.map((w) => h("div", { text: `⚠ ${w}` })));
}

async function renderRuns() {
  renderRunsTable();
  if (state.tab !== "run" || !state.runsDirty) return;
  state.runsDirty = false;
  const a = state.runA ? await runPayload(state.runA) : null;
  const b = state.runB ? await runPayload(state.runB) : null;
  if (!a) {
    $("#summary-table").replaceChildren();
    $("#sections-table").replaceChildren();
    for (const id of ["#plot-speed-distance", "#plot-speed-time", "#plot-power", "#plot-energy"]) Plotly.purge($(id));
    return;
  }
  renderSummary(a, b);
  plotRuns({ speedDistance: $("#plot-speed-distance"), speedTime: $("#plot-speed-time"), power: $("#plot-power"),
    energy: $("#plot-energy") }, b ? [a, b] : [a]);
}

function renderStrategyParams() {
  const chosen = state.strategies.find((s) => s.name === $("#run-strategy").value);
  const box = $("#run-params");
  box.replaceChildren();
  for (const [key, prop] of Object.entries(chosen?.params_schema?.properties || {})) {
    const isList = prop.type === "array" || (prop.anyOf || []).some((x) => x.type === "array");
    const isPoints = key === "timing_points";
    const input = h("input", { type: "text", class: isList ? "txt" : "num", "data-param": key, "data-path": `params.${key}`,
      "data-list": isList && !isPoints ? "true" : undefined, "data-points": isPoints ? "true" : undefined,
      title: isPoints ? "position: time window from the section's departure @ speed window, e.g. "
        + "800: 60-120 @ 40-60 km/h; 2400: -300; 3000: @ -50" : prop.description || key,
      placeholder: isPoints ? "e.g. 800: 60-120 @ 40-60 km/h; 2400: -300" : isList ? "e.g. 110, 100, 95"
        : prop.default !== undefined && prop.default !== null ? String(prop.default) : "" });
    box.append(h("label", { title: prop.description || key }, key, input));
  }
}

// ------------------------------------------------------------ live driving
const drive = {
  ws: null,
  notch: 0,
  plot: null,
  running: false,
  paused: false,
  lastRun: null,
};
const NOTCH_NAMES = { "-4": "B4", "-3": "B3", "-2": "B2", "-1": "B1", 0: "N", 1: "P1", 2: "P2", 3: "P3", 4: "P4" };

function driveSend(msg) {
  if (drive.ws && drive.ws.readyState === WebSocket.OPEN) drive.ws.send(JSON.stringify(msg));
}

function setNotch(n) {
  drive.notch = Math.max(-4, Math.min(4, n));
  $("#drive-lever").value = drive.notch;
  $("#drive-notch").textContent = NOTCH_NAMES[drive.notch];
  driveSend({ type: "command", value: drive.notch / 4 });
}

function driveControls(on) {
  for (const id of ["#drive-accel", "#drive-brake", "#drive-neutral", "#drive-full-brake", "#drive-lever", "#drive-pause", "#drive-finish"]) {
    $(id).disabled = !on;
  }
}

function showDriveState(s) {
  $("#drive-speed").textContent = fmt(s.speed_kmh, 1);
  $("#drive-speed").parentElement.classList.toggle("over", s.overspeed);
  $("#drive-limit").textContent = fmt(s.speed_limit_kmh, 0);
  $("#drive-next-limit").textContent = s.next_limit_kmh === null ? "–"
    : `${fmt(s.next_limit_kmh, 0)} km/h in ${fmt(s.next_limit_distance_m, 0)} m`;
  $("#drive-next-stop").textContent = s.next_stop_name === null ? "–" : `${s.next_stop_name} in ${fmt(s.next_stop_distance_m, 0)} m`;
  $("#drive-position").textContent = fmt(s.position_m / 1000, 3);
  $("#drive-time").textContent = fmt(s.clock_s, 0);
  $("#drive-accel-value").textContent = fmt(s.acceleration_mps2, 2);
  $("#drive-effort").textContent = s.braking_force_kn > 0 ? `−${fmt(s.braking_force_kn, 0)}` : fmt(s.traction_force_kn, 0);
  $("#drive-gradient").textContent = fmt(s.gradient_permille, 1);
  $("#drive-current").textContent = fmt(s.line_current_a, 0);
  $("#drive-energy").textContent = fmt(s.energy_kwh, 2);
  $("#drive-dwell").textContent = s.dwell_remaining_s > 0 ? fmt(s.dwell_remaining_s, 0) : "–";
  $("#drive-stop-error").textContent = s.stop_error_m === null ? "–"
    : `${s.stop_error_m >= 0 ? "+" : ""}${fmt(s.stop_error_m, 1)}`;
  if (s.lever_reset && drive.notch !== 0) setNotch(0);
  const atp = s.atp_braking ? "ATP BRAKING — " : "";
  $("#drive-message").textContent = `${atp}${s.overspeed ? "⚠ OVERSPEED — " : ""}${s.location} · ${s.message} · ${s.regime}${s.paused ? " · paused" : ""} · ${s.time_scale}x`;
  $("#drive-speed").dataset.value = s.speed_kmh;
  $("#drive-position").dataset.value = s.position_m;
  $("#drive-next-stop").dataset.distance = s.next_stop_distance_m ?? "";
  $("#drive-dwell").dataset.value = s.dwell_remaining_s;
  drive.plot.update(s);
}

function startDrive() {
  if (drive.ws) drive.ws.close();
  const proto = location.protocol === "https:" ? "wss" : "ws";
  const ws = new WebSocket(`${proto}://${location.host}/api/drive`);
  drive.ws = ws;
  drive.plot = drive.plot || new DrivePlot($("#drive-plot"));
  $("#drive-result").hidden = true;
  ws.addEventListener("open", () => {
    const scale = Number(document.querySelector("input[name=scale]:checked").value);
    ws.send(JSON.stringify({ type: "start", time_scale: scale, clock: "realtime", atp: $("#drive-atp").checked }));
  });
  ws.addEventListener("message", (ev) => {
    const msg = JSON.parse(ev.data);
    if (msg.type === "init") {
      drive.plot.init(msg.profile, msg.reference, msg.max_speed_kmh);
      drive.running = true;
      drive.paused = false;
      $("#drive-pause").textContent = "Pause";
      driveControls(true);
      setNotch(0);
      $("#drive-start").textContent = "Restart drive";
    } else if (msg.type === "state") {
      if (ws === drive.ws) showDriveState(msg);
    } else if (msg.type === "finished") {
      drive.running = false;
      driveControls(false);
      $("#drive-message").textContent = `Drive ended: ${msg.reason}`;
      drive.lastRun = msg.run;
      if (msg.run) showDriveResult(msg);
      refreshRuns();
    } else if (msg.type === "error") {
      $("#drive-message").textContent = `✗ ${msg.message}`;
    } else if (msg.type === "ended") {
      driveControls(false);
      $("#drive-message").textContent = `Drive ended: ${msg.reason}`;
    }
  });
  ws.addEventListener("close", () => {
    if (ws === drive.ws) {
      drive.running = false;
      driveControls(false);
    }
  });
}

function showDriveResult(msg) {
  const s = msg.summary;
  const rows = [["running time", `${fmt(s.running_time_s, 1)} s`], ["total time", `${fmt(s.total_time_s, 1)} s`],
    ["net energy", `${fmt(s.energy_kwh.net, 2)} kWh`], ["status", s.status], ...s.warnings.map((w) => ["warning", w])];
  $("#drive-summary").replaceChildren(h("tr", {}, h("th", { colspan: 2, text: msg.run.label })),
    ...rows.map(([k, v]) => h("tr", {}, h("td", { text: k }), h("td", { text: v }))));
  $("#drive-result").hidden = false;
}

async function compareDrive() {
  if (!drive.lastRun) return;
  // the fastest run of the drive's own train and line over the same distance (not any run in the list)
  const answer = await busy(post(`/api/runs/${drive.lastRun.id}/fastest`, {}));
  if (!answer.ok) {
    $("#drive-message").textContent = `✗ ${answer.data.message}`;
    return;
  }
  state.cache.set(answer.data.id, answer.data);
  await refreshRuns();
  state.runA = drive.lastRun.id;
  state.runB = answer.data.id;
  state.runsDirty = true;
  switchTab("run");
}

async function energyTimeCurve() {
  const answer = await busy(post("/api/curves/energy-time", {}));
  if (!answer.ok) {
    showErrors($("#run-errors"), answer.data, answer.data.detail);
    return;
  }
  showErrors($("#run-errors"), null);
  const div = $("#plot-energy-time");
  div.hidden = false;
  plotEnergyTime(div, answer.data.points);
}

async function runMultipoint() {
  const name = $("#mp-example").value;
  setStatus($("#mp-status"), "running (the first run of an example takes a while)…", "");
  showMultipoint(await busy(post(`/api/multipoint/${encodeURIComponent(name)}`, {})));
}

async function uploadMultipoint(ev) {
  const file = ev.target.files[0];
  ev.target.value = "";
  if (!file) return;
  setStatus($("#mp-status"), `running ${file.name}…`, "");
  showMultipoint(await busy(upload("/api/multipoint/upload", file)));
}

function showMultipoint(answer) {
  if (!answer.ok) {
    // the readers' messages, one per file, line and field (as the command line prints them)
    setStatus($("#mp-status"), `✗ ${answer.data.message}`, "bad");
    $("#mp-extremes").replaceChildren(...(answer.data.detail || []).map((d) => h("div", {
      class: "bad", text: `${d.file ? `${d.file}${d.line ? `:${d.line}` : ""}: ` : ""}${d.field ? `${d.field}: ` : ""}${d.msg}` })));
    return;
  }
  const mp = answer.data;
  setStatus($("#mp-status"), `✓ ${mp.status}: running time ${fmt(mp.running_time_s, 1)} s, net energy ${fmt(mp.energy_net_kwh, 1)} kWh`, "ok");
  const line = (e, what) => `${what}: ${fmt(Math.abs(e.force_kn), 0)} kN at coupling ${e.coupler} (behind ${e.behind_vehicle}), `
    + `${fmt(e.time_s, 0)} s, head at ${fmt(e.head_position_m / 1000, 2)} km`;
  $("#mp-extremes").replaceChildren(h("div", { text: line(mp.max_draft, "largest draft") }),
    h("div", { text: line(mp.max_buff, "largest buff") }), ...mp.warnings.map((w) => h("div", { text: `⚠ ${w}` })));
  const div = $("#plot-couplers");
  div.hidden = false;
  plotCouplerHeatmap(div, mp);
}

const operation = { data: null, plot: "graph" };
const OP_PLOTS = {
  graph: ["#plot-train-graph", plotTrainGraph],
  delays: ["#plot-op-delays", plotOperationDelays],
  headways: ["#plot-op-headways", plotOperationHeadways],
};

async function runOperation() {
  const name = $("#op-example").value;
  setStatus($("#op-status"), "running the operation…", "");
  showOperation(await busy(post(`/api/operations/${encodeURIComponent(name)}`, {})));
}

async function uploadOperation(ev) {
  const file = ev.target.files[0];
  ev.target.value = "";
  if (!file) return;
  setStatus($("#op-status"), `running ${file.name}…`, "");
  showOperation(await busy(upload("/api/operations/upload", file)));
}

function showOperation(answer) {
  if (!answer.ok) {
    // the readers' messages, one per file, line and field (as the command line prints them)
    setStatus($("#op-status"), `✗ ${answer.data.message}`, "bad");
    $("#op-warnings").replaceChildren(...(answer.data.detail || []).map((d) => h("div", {
      class: "bad", text: `${d.file ? `${d.file}${d.line ? `:${d.line}` : ""}: ` : ""}${d.field ? `${d.field}: ` : ""}${d.msg}` })));
    return;
  }
  const op = answer.data;
  operation.data = op;
  const n = op.conflicts.length;
  // a status other than ok (conflicts, deadlock, stalled) is shown as such, never as a success
  setStatus($("#op-status"), `${op.status === "ok" ? "✓" : "⚠"} ${op.status}: ${op.trains.length} trains, `
    + `${n} conflict${n === 1 ? "" : "s"}, total delay ${fmt(op.total_delay_s, 0)} s`, op.status === "ok" ? "ok" : "bad");
  const notes = [...op.warnings];
  if (op.deadlock.length) notes.unshift(`deadlock: ${op.deadlock.join(", ")}`);
  for (const t of op.trains) for (const w of t.warnings) notes.push(`${t.id}: ${w}`);
  $("#op-warnings").replaceChildren(...notes.map((w) => h("div", { text: `⚠ ${w}` })));
  $("#op-conflicts").replaceChildren(...(n ? [
    h("tr", {}, ...["conflict", "trains", "block", "resource", "time", "overlap [s]"].map((c) => h("th", { text: c }))),
    ...op.conflicts.map((c, i) => h("tr", {}, h("td", { text: String(i + 1) }), h("td", { text: `${c.trains[0]} → ${c.trains[1]}` }),
      h("td", { text: c.block }), h("td", { text: c.resource }), h("td", { text: clock(c.time_s) }),
      h("td", { class: "num", text: fmt(c.overlap_s, 1) }))),
  ] : []));
  $("#op-tabs").hidden = false;
  showOperationPlot(operation.plot);
}

function showOperationPlot(which) {
  operation.plot = which;
  for (const b of document.querySelectorAll("#op-tabs button")) b.classList.toggle("active", b.dataset.opPlot === which);
  for (const [key, [sel]] of Object.entries(OP_PLOTS)) $(sel).hidden = key !== which;
  const [sel, draw] = OP_PLOTS[which];
  if (operation.data) draw($(sel), operation.data); // drawn when shown: a hidden div has no size
}

function driveKeys(ev) {
  if (state.tab !== "drive" || !drive.running) return;
  if (["INPUT", "SELECT", "TEXTAREA"].includes(document.activeElement?.tagName) && document.activeElement.type !== "range"
      && document.activeElement.type !== "radio") return;
  const key = ev.key.toLowerCase();
  const actions = {
    arrowup: () => setNotch(drive.notch + 1), w: () => setNotch(drive.notch + 1),
    arrowdown: () => setNotch(drive.notch - 1), s: () => setNotch(drive.notch - 1),
    n: () => setNotch(0), b: () => setNotch(-4), " ": () => $("#drive-pause").click(),
    1: () => setScale(1), 5: () => setScale(5), 2: () => setScale(20),
  };
  if (actions[key]) {
    ev.preventDefault();
    actions[key]();
  }
}

function setScale(value) {
  const radio = document.querySelector(`input[name=scale][value="${value}"]`);
  radio.checked = true;
  driveSend({ type: "time_scale", value });
}

// ------------------------------------------------------------ start
async function main() {
  for (const b of document.querySelectorAll("#tabs button")) b.addEventListener("click", () => switchTab(b.dataset.tab));
  const [examples, strategies, operations] = await Promise.all([get("/api/examples"), get("/api/strategies"), get("/api/operations")]);
  if (operations.ok) {
    $("#op-example").replaceChildren(...operations.data.map((e) => h("option", { value: e.name, text: `${e.name} — ${e.description}` })));
  }
  state.examples = examples.data;
  state.strategies = strategies.data;
  $("#example-select").replaceChildren(...state.examples.map((e) => h("option", { value: e.name, text: `${e.name} — ${e.description}` })));
  $("#run-strategy").replaceChildren(...state.strategies.map((s) => h("option", { value: s.name, text: s.label, title: s.description })));
  $("#run-strategy").addEventListener("change", renderStrategyParams);
  renderStrategyParams();
  $("#example-load").addEventListener("click", async () => {
    const name = $("#example-select").value;
    const answer = await busy(post(`/api/examples/${encodeURIComponent(name)}`));
    if (!answer.ok) return;
    trainPage.loaded(answer.data.train, `example ${name}`);
    routePage.loaded(answer.data.route, `example ${name}`);
    await refreshSession();
    changedInputs();
  });
  await refreshSession();
  await Promise.all([trainPage.init(), routePage.init()]);
  await refreshRuns();
  $("#run-button").addEventListener("click", async () => {
    await doRun("manual");
    renderRuns();
  });
  // live driving
  $("#drive-start").addEventListener("click", startDrive);
  $("#drive-accel").addEventListener("click", () => setNotch(drive.notch + 1));
  $("#drive-brake").addEventListener("click", () => setNotch(drive.notch - 1));
  $("#drive-neutral").addEventListener("click", () => setNotch(0));
  $("#drive-full-brake").addEventListener("click", () => setNotch(-4));
  $("#drive-lever").addEventListener("input", (ev) => setNotch(Number(ev.target.value)));
  $("#drive-pause").addEventListener("click", () => {
    drive.paused = !drive.paused;
    driveSend({ type: drive.paused ? "pause" : "resume" });
    $("#drive-pause").textContent = drive.paused ? "Resume" : "Pause";
  });
  $("#drive-finish").addEventListener("click", () => driveSend({ type: "finish" }));
  $("#drive-compare").addEventListener("click", compareDrive);
  $("#curve-button").addEventListener("click", energyTimeCurve);
  $("#mp-run").addEventListener("click", runMultipoint);
  $("#mp-file").addEventListener("change", uploadMultipoint);
  $("#op-run").addEventListener("click", runOperation);
  $("#op-file").addEventListener("change", uploadOperation);
  for (const b of document.querySelectorAll("#op-tabs button")) b.addEventListener("click", () => showOperationPlot(b.dataset.opPlot));
  for (const r of document.querySelectorAll("input[name=scale]")) r.addEventListener("change", () => setScale(Number(r.value)));
  document.addEventListener("keydown", driveKeys);
  document.body.dataset.ready = "true";
}

main();
