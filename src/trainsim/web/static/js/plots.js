// Plotly figures: effort/resistance over speed, line profile, run plots, live driving profile.
// Plotly is served by the server from the installed plotly Python package (no CDN).

// every plot downloads as PNG (the camera button) or SVG (the button beside it)
const SVG_BUTTON = {
  name: "downloadSvg",
  title: "Download plot as SVG",
  icon: window.Plotly ? window.Plotly.Icons.disk : undefined,
  click: (gd) => window.Plotly.downloadImage(gd, { format: "svg", filename: "trainsim-plot" }),
};
const CONFIG = {
  responsive: true, displaylogo: false, modeBarButtonsToRemove: ["lasso2d", "select2d"],
  modeBarButtonsToAdd: [SVG_BUTTON], toImageButtonOptions: { format: "png", filename: "trainsim-plot", scale: 2 },
};
const COLORS = { a: "#1f77b4", b: "#ff7f0e", limit: "#d62728", grade: "#8c564b", ref: "#7f7f7f" };
const BASE = {
  margin: { l: 60, r: 60, t: 36, b: 44 },
  font: { size: 12 },
  legend: { orientation: "h", y: -0.2 },
  hovermode: "x unified",
};

const stepXY = (sections, lo, hi, scale = 1) => {
  // x, y of a piecewise constant function given as [from, to, value] (0 where none)
  const xs = [];
  const ys = [];
  let pos = lo;
  for (const [a, b, v] of [...sections].sort((p, q) => p[0] - q[0])) {
    if (a > pos) xs.push(pos / scale, a / scale), ys.push(0, 0);
    xs.push(a / scale, b / scale);
    ys.push(v, v);
    pos = b;
  }
  if (pos < hi) xs.push(pos / scale, hi / scale), ys.push(0, 0);
  return { x: xs, y: ys };
};

function stationShapes(profile) {
  const shapes = [];
  const annotations = [];
  for (const s of profile.stations) {
    const x = s.position_m / 1000;
    shapes.push({ type: "line", xref: "x", yref: "paper", x0: x, x1: x, y0: 0, y1: 1,
      line: { color: "#444", width: 1, dash: s.stop ? "solid" : "dot" } });
    annotations.push({ x, y: 1, xref: "x", yref: "paper", text: s.name, showarrow: false,
      textangle: -90, xanchor: "left", yanchor: "top", font: { size: 10, color: "#333" } });
  }
  for (const [a, b] of profile.tunnels) {
    shapes.push({ type: "rect", xref: "x", yref: "paper", x0: a / 1000, x1: b / 1000, y0: 0, y1: 0.04,
      fillcolor: "#555", opacity: 0.5, line: { width: 0 } });
  }
  for (const [a, b] of profile.curves) {
    shapes.push({ type: "rect", xref: "x", yref: "paper", x0: a / 1000, x1: b / 1000, y0: 0.04, y1: 0.07,
      fillcolor: "#2ca02c", opacity: 0.5, line: { width: 0 } });
  }
  return { shapes, annotations };
}

function profileTraces(profile, { withLimits = true } = {}) {
  const grade = stepXY(profile.gradients, profile.start_m, profile.end_m, 1000);
  const traces = [
    { x: grade.x, y: grade.y, yaxis: "y2", name: "gradient [‰]", mode: "lines", fill: "tozeroy",
      line: { color: COLORS.grade, width: 1 }, fillcolor: "rgba(140,86,75,0.15)", hovertemplate: "%{y:.1f} ‰" },
  ];
  if (withLimits) {
    const lim = stepXY(profile.speed_limits, profile.start_m, profile.end_m, 1000);
    traces.push({ x: lim.x, y: lim.y, name: "line speed limit", mode: "lines",
      line: { color: COLORS.limit, width: 1.5, dash: "dot" }, hovertemplate: "%{y:.0f} km/h" });
  }
  // legend entries for the marks along the bottom (shapes have none of their own)
  const mark = (name, color) => ({ x: [null], y: [null], name, mode: "markers", hoverinfo: "skip",
    marker: { symbol: "square", size: 11, color, opacity: 0.6 } });
  if (profile.curves.length) traces.push(mark("curve", "#2ca02c"));
  if (profile.tunnels.length) traces.push(mark("tunnel", "#555"));
  return traces;
}

function profileLayout(profile, title, extra = {}) {
  const grades = profile.gradients.map((g) => Math.abs(g[2]));
  const span = Math.max(1, ...grades);
  const limits = profile.speed_limits.map((s) => s[2]);
  const { shapes, annotations } = stationShapes(profile);
  return {
    ...BASE,
    title: { text: title, font: { size: 14 } },
    // speed above, the gradient profile in a band below it on the same distance axis
    xaxis: { title: { text: "distance [km]" }, range: [profile.start_m / 1000, profile.end_m / 1000], anchor: "y2" },
    yaxis: { title: { text: "speed [km/h]" }, range: [0, Math.max(...limits, extra.topSpeed || 0, 10) * 1.15],
      domain: [0.3, 1] },
    yaxis2: { title: { text: "gradient [‰]" }, range: [-1.2 * span, 1.2 * span], domain: [0, 0.22], zeroline: true },
    shapes,
    annotations,
    ...Object.fromEntries(Object.entries(extra).filter(([k]) => k !== "topSpeed")),
  };
}

export function plotProfile(div, profile) {
  Plotly.react(div, profileTraces(profile), profileLayout(profile, `Line profile — ${profile.name}`), CONFIG);
}

export function plotTrainCurves(div, curves, name) {
  const x = curves.speed_kmh;
  const traces = [
    { x, y: curves.traction_kn, name: "maximum traction", line: { color: COLORS.a, width: 2 } },
    { x, y: curves.braking_kn, name: curves.braking_label, line: { color: COLORS.limit, width: 2 } },
    { x, y: curves.resistance_kn, name: "running resistance (level)", line: { color: "#000", width: 1.5 } },
    { x, y: curves.resistance_10_permille_kn, name: "resistance on 10 ‰", line: { color: "#000", width: 1, dash: "dash" } },
  ];
  if (curves.regenerative_kn) traces.push({ x, y: curves.regenerative_kn, name: "regenerative braking", line: { color: "#2ca02c" } });
  Plotly.react(div, traces, {
    ...BASE,
    title: { text: `Effort and resistance — ${name}`, font: { size: 14 } },
    xaxis: { title: { text: "speed [km/h]" } },
    yaxis: { title: { text: "force [kN]" }, rangemode: "tozero" },
  }, CONFIG);
}

// ------------------------------------------------------------ runs
export function plotRuns(divs, runs) {
  const [a] = runs;
  const name = (r) => r.label;
  const color = (i) => (i === 0 ? COLORS.a : COLORS.b);
  // speed over distance with the line profile of the first run
  const sd = [...profileTraces(a.profile)];
  sd.push({ x: a.plot.position_m.map((x) => x / 1000), y: a.plot.speed_limit_kmh, name: "speed ceiling (train)",
    line: { color: COLORS.limit, width: 1, shape: "hv" }, opacity: 0.6 });
  runs.forEach((r, i) => sd.push({ x: r.plot.position_m.map((x) => x / 1000), y: r.plot.speed_kmh, name: `speed: ${name(r)}`,
    line: { color: color(i), width: 2 } }));
  const topSpeed = Math.max(...runs.flatMap((r) => [...r.plot.speed_kmh, ...r.plot.speed_limit_kmh]).filter((v) => v !== null));
  Plotly.react(divs.speedDistance, sd, profileLayout(a.profile, "Speed over distance", { topSpeed }), CONFIG);

  const st = runs.map((r, i) => ({ x: r.plot.time_s, y: r.plot.speed_kmh, name: name(r), line: { color: color(i), width: 2 } }));
  Plotly.react(divs.speedTime, st, { ...BASE, title: { text: "Speed over time", font: { size: 14 } },
    xaxis: { title: { text: "time [s]" } }, yaxis: { title: { text: "speed [km/h]" }, rangemode: "tozero" } }, CONFIG);

  const pc = [];
  runs.forEach((r, i) => {
    pc.push({ x: r.plot.time_s, y: r.plot.electrical_power_kw.map((v) => (v === null ? null : v / 1000)), name: `line power: ${name(r)}`,
      line: { color: color(i), width: 1.5 } });
    pc.push({ x: r.plot.time_s, y: r.plot.line_current_a, name: `line current: ${name(r)}`, yaxis: "y2", xaxis: "x2",
      line: { color: color(i), width: 1.5, dash: "dot" } });
  });
  Plotly.react(divs.power, pc, { ...BASE, title: { text: "Power and line current", font: { size: 14 } },
    grid: { rows: 2, columns: 1, pattern: "independent" },
    xaxis: { title: { text: "" }, matches: "x2" }, yaxis: { title: { text: "power [MW]" } },
    xaxis2: { title: { text: "time [s]" } }, yaxis2: { title: { text: "current [A]" } } }, CONFIG);

  const en = [];
  runs.forEach((r, i) => {
    const sections = r.summary.sections;
    const labels = sections.map((s) => `${s.from} → ${s.to}`);
    en.push({ type: "bar", x: labels, y: sections.map((s) => s.energy_kwh.net), name: `net from line: ${name(r)}`,
      marker: { color: color(i) }, texttemplate: "%{y:.1f}", textposition: "outside" });
    en.push({ type: "bar", x: labels, y: sections.map((s) => s.energy_kwh.traction), name: `traction at wheel: ${name(r)}`,
      marker: { color: color(i), opacity: 0.45 } });
  });
  Plotly.react(divs.energy, en, { ...BASE, hovermode: "closest", barmode: "group",
    title: { text: "Energy by section", font: { size: 14 } }, yaxis: { title: { text: "energy [kWh]" } } }, CONFIG);
}

// ------------------------------------------------------------ live driving
export class DrivePlot {
  constructor(div) {
    this.div = div;
    this.pending = null;
    this.last = 0;
  }

  init(profile, reference, maxSpeed) {
    const traces = profileTraces(profile);
    if (reference) traces.push({ x: reference.position_m.map((x) => x / 1000), y: reference.speed_kmh,
      name: `fastest run (${reference.running_time_s.toFixed(1)} s)`, line: { color: COLORS.ref, width: 1.5, dash: "dash" } });
    traces.push({ x: [], y: [], name: "your drive", line: { color: COLORS.a, width: 2 } });
    traces.push({ x: [profile.stations[0].position_m / 1000], y: [0], name: "train", mode: "markers",
      marker: { size: 14, symbol: "triangle-right", color: "#000" } });
    this.driveIndex = traces.length - 2;
    Plotly.react(this.div, traces, profileLayout(profile, "Your drive on the line", { hovermode: "closest", topSpeed: maxSpeed }), CONFIG);
  }

  update(state) {
    // drawn at most 5 times a second; the points in between are kept
    const x = state.position_m / 1000;
    this.pending = this.pending || { x: [], y: [] };
    this.pending.x.push(x);
    this.pending.y.push(state.speed_kmh);
    const now = performance.now();
    if (now - this.last < 200 && !state.finished) return;
    this.last = now;
    const { x: xs, y: ys } = this.pending;
    this.pending = null;
    Plotly.extendTraces(this.div, { x: [xs], y: [ys] }, [this.driveIndex]);
    Plotly.restyle(this.div, { x: [[x]], y: [[state.speed_kmh]] }, [this.driveIndex + 1]);
  }
}

// Net energy from the line against running time (the energy-efficient strategy, line supplements)
export function plotEnergyTime(div, points) {
  const x = points.map((p) => p.running_time_s);
  Plotly.react(div, [
    { x, y: points.map((p) => p.energy_kwh), name: "net energy from line", mode: "lines+markers",
      text: points.map((p) => `+${p.supplement_percent} %`), hovertemplate: "%{x:.1f} s, %{y:.2f} kWh (%{text})",
      line: { color: COLORS.a } },
    { x, y: points.map((p) => p.energy_traction_kwh), name: "traction energy (wheel)", mode: "lines+markers",
      line: { color: COLORS.b, dash: "dot" } },
  ], { ...BASE, hovermode: "closest", title: { text: "Energy against running time (energy-efficient)", font: { size: 14 } },
    xaxis: { title: { text: "running time [s]" } }, yaxis: { title: { text: "energy [kWh]" } } }, CONFIG);
}

// Coupler force over time and coupling (head at the top): draft red, buff blue; extremes marked
export function plotCouplerHeatmap(div, mp) {
  const hm = mp.heatmap;
  const lim = Math.max(1, ...hm.force_kn.map((row) => Math.max(...row.map(Math.abs))));
  const ext = (e, label, symbol) => ({ x: [e.time_s], y: [e.coupler], mode: "markers", name: `${label} ${e.force_kn.toFixed(0)} kN`,
    marker: { symbol, size: 12, color: "#000" }, hovertemplate: `${label}: %{x:.0f} s, coupler %{y}<extra></extra>` });
  Plotly.react(div, [
    { type: "heatmap", x: hm.time_s, y: hm.force_kn.map((_, i) => i), z: hm.force_kn, zmid: 0, zmin: -lim, zmax: lim,
      colorscale: "RdBu", reversescale: false, colorbar: { title: { text: "kN" } }, name: "coupler force",
      hovertemplate: "%{x:.0f} s, coupler %{y}: %{z:.0f} kN<extra></extra>" },
    ext(mp.max_draft, "max draft", "triangle-down"),
    ext(mp.max_buff, "max buff", "triangle-up"),
  ], { ...BASE, hovermode: "closest", title: { text: `In-train forces (draft > 0, buff < 0): ${mp.train}`, font: { size: 14 } },
    xaxis: { title: { text: "time [s]" } }, yaxis: { title: { text: "coupling (0 = behind the head vehicle)" }, autorange: "reversed" } }, CONFIG);
}

// ---------------------------------------------------------------- a line in operation (issue 17)
const PALETTE = ["#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b", "#e377c2", "#17becf", "#bcbd22", "#7f7f7f"];
export const clock = (s) => {
  const t = Math.round(s);
  const pad = (n) => String(n).padStart(2, "0");
  return `${pad(Math.floor(t / 3600))}:${pad(Math.floor((t % 3600) / 60))}:${pad(t % 60)}`;
};
// a date axis reads numbers as ms: times after midnight become clock times that zoom well
const ms = (times) => times.map((s) => (s === null ? null : s * 1000));
const trainColours = (op) => new Map(op.trains.map((t, i) => [t.id, PALETTE[i % PALETTE.length]]));

// train graph: time across, line position up; each train's operated run (solid) and its timetable
// (dashed), its blocking times as the "stairs" of rectangles (resource from_m..to_m blocked from
// start_s to end_s), and the planned timetable's conflicts as red boxes with a marker to hover
export function plotTrainGraph(div, op) {
  const colour = trainColours(op);
  const byTrain = new Map(op.trains.map((t) => [t.id, { x: [], y: [] }]));
  for (const b of op.blocking) {
    const s = byTrain.get(b.train);
    if (!s) continue;
    s.x.push(b.start_s, b.end_s, b.end_s, b.start_s, b.start_s, null);
    s.y.push(b.from_m, b.from_m, b.to_m, b.to_m, b.from_m, null);
  }
  const stairs = op.trains.map((t) => ({ x: ms(byTrain.get(t.id).x), y: byTrain.get(t.id).y, mode: "lines", fill: "toself",
    line: { width: 0.5, color: colour.get(t.id) }, opacity: 0.25, name: `${t.id} blocking`, legendgroup: t.id,
    showlegend: false, hoverinfo: "skip" }));
  const planned = op.trains.map((t) => ({ x: ms(t.planned_time_s), y: t.planned_position_m, mode: "lines",
    name: `${t.id} planned`, legendgroup: t.id, showlegend: false, line: { color: colour.get(t.id), width: 1, dash: "dash" },
    hovertemplate: `${t.id} planned: %{x|%H:%M:%S}, %{y:.0f} m<extra></extra>` }));
  const paths = op.trains.map((t) => ({ x: ms(t.time_s), y: t.position_m, mode: "lines", name: t.id, legendgroup: t.id,
    line: { color: colour.get(t.id), width: 2 },
    hovertemplate: `${t.id}${t.operated ? "" : " (not operated: planned)"}: %{x|%H:%M:%S}, %{y:.0f} m `
      + `(${t.status}, delay ${t.delay_s === null ? "–" : t.delay_s.toFixed(0)} s)<extra></extra>` }));
  const traces = [...stairs, ...planned, ...paths];
  const placed = op.conflicts.filter((c) => c.from_m !== null);
  if (placed.length) {
    const box = { x: [], y: [] };
    for (const c of placed) {
      const t1 = c.time_s + c.overlap_s;
      box.x.push(c.time_s, t1, t1, c.time_s, c.time_s, null);
      box.y.push(c.from_m, c.from_m, c.to_m, c.to_m, c.from_m, null);
    }
    traces.push({ x: ms(box.x), y: box.y, mode: "lines", line: { color: "#d62728", width: 2 }, name: "conflict boxes",
      legendgroup: "conflicts", showlegend: false, hoverinfo: "skip" });
    traces.push({ x: placed.map((c) => (c.time_s + c.overlap_s / 2) * 1000), y: placed.map((c) => (c.from_m + c.to_m) / 2),
      mode: "markers", name: `conflicts (${op.conflicts.length})`, legendgroup: "conflicts",
      marker: { symbol: "x", size: 11, color: "#d62728", line: { width: 1, color: "#fff" } },
      text: placed.map((c) => `conflict: ${c.trains[0]} → ${c.trains[1]}<br>block ${c.block} (${c.resource})`
        + `<br>at ${clock(c.time_s)}, overlap ${c.overlap_s.toFixed(1)} s`),
      hovertemplate: "%{text}<extra></extra>" });
  }
  const stations = op.stations.map((s) => ({ type: "line", xref: "paper", x0: 0, x1: 1, y0: s.position_m, y1: s.position_m,
    line: { color: "#999", width: 1, dash: "dot" } }));
  const labels = op.stations.map((s) => ({ xref: "paper", x: 1, xanchor: "left", y: s.position_m, text: s.name,
    showarrow: false, font: { size: 11 } }));
  const n = op.conflicts.length;
  Plotly.react(div, traces, { ...BASE, hovermode: "closest", shapes: stations, annotations: labels, height: 560,
    title: { text: `Train graph with blocking times: ${op.title} (${op.signalling}, ${n} conflict${n === 1 ? "" : "s"})`,
      font: { size: 14 } },
    xaxis: { title: { text: "time (solid: operated, dashed: timetable; shaded: blocking times; red ×: conflicts of the timetable)" },
      type: "date", tickformat: "%H:%M" },
    yaxis: { title: { text: "position on the line [m]" } } }, CONFIG);
}

// delay of each train at each station it has a time at (departure; arrival at the destination)
export function plotOperationDelays(div, op) {
  const colour = trainColours(op);
  const names = op.stations.map((s) => s.name);
  const traces = op.trains.map((t) => {
    const stops = t.stops.filter((s) => s.delay_s !== null);
    return { x: stops.map((s) => s.station), y: stops.map((s) => s.delay_s), mode: "lines+markers", name: t.id,
      line: { color: colour.get(t.id), width: 1.5 }, marker: { size: 6 },
      text: stops.map((s) => s.kind), hovertemplate: `${t.id} at %{x} (%{text}): %{y:.0f} s<extra></extra>` };
  });
  Plotly.react(div, traces, { ...BASE, hovermode: "closest",
    title: { text: `Delay per station: ${op.title} (total ${op.total_delay_s === null ? "–" : op.total_delay_s.toFixed(0)} s)`,
      font: { size: 14 } },
    xaxis: { title: { text: "station (in line order)" }, type: "category", categoryorder: "array", categoryarray: names },
    yaxis: { title: { text: "delay [s]" }, zeroline: true } }, CONFIG);
}

// for each pair of consecutive planned trains: the headway each shared resource needs over the line;
// the highest point of a pair's line is its minimum headway
export function plotOperationHeadways(div, op) {
  const traces = op.headways.map((h, i) => ({ x: h.position_m.map((x) => x / 1000), y: h.headway_s, mode: "lines+markers",
    name: `${h.leader} → ${h.follower}`, line: { color: PALETTE[i % PALETTE.length], width: 1.5 }, marker: { size: 4 },
    hovertemplate: `${h.leader} → ${h.follower}: needs %{y:.0f} s at %{x:.2f} km<br>minimum ${h.min_headway_s.toFixed(0)} s `
      + `(block ${h.critical_block}), planned ${h.planned_headway_s.toFixed(0)} s, buffer ${h.buffer_s.toFixed(0)} s<extra></extra>` }));
  Plotly.react(div, traces, { ...BASE, hovermode: "closest",
    title: { text: `Headway over the line (consecutive planned trains; the highest point is the minimum headway)`, font: { size: 14 } },
    xaxis: { title: { text: "line position [km]" } }, yaxis: { title: { text: "headway needed [s]" } } }, CONFIG);
}
