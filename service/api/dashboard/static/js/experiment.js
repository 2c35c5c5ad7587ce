// Experiment page: the treatments side by side, from GET /experiments/{id}/analysis
// (service.reports.report.experiment): fitness curves and the runs' QD score and coverage with
// 95% intervals over runs, aggregated
// Pareto fronts, descriptor distributions, the statistics table with families, every run,
// and the downloads (GET /experiments/{id}/export). Polled while a run is live.
import { LIVE, el, errorLine, fill, fmt, getJSON, page, poll, progressBar, root, showHealth, table } from "./api.js";
import { FONT, LEGEND_RIGHT, MARGIN, PLOT_CONFIG, plotlyMissing, withAlpha } from "./plots.js";

const experimentId = Number(document.getElementById("experiment").dataset.experiment);
const LIVE_POLL_MS = 30000; // the analysis is an expensive read: recomputed once per change at most
const IDLE_POLL_MS = null;
const TABLES = ["runs", "individuals", "populations"];
const FORMATS = ["csv", "parquet"];
const SMALL_MARGIN = { l: 50, r: 10, t: 28, b: 40 }; // the toolbar sits in the top margin; titles above the plot

const state = { analysis: null };

function downloads() {
  const links = [];
  for (const format of FORMATS) {
    for (const name of TABLES) {
      const href = `${root}/experiments/${experimentId}/export?table=${name}&format=${format}`;
      links.push(el("a", { href, download: `experiment-${experimentId}-${name}.${format}`, class: "download" }, `${name}.${format}`));
    }
  }
  fill("downloads", links.flatMap((link, i) => (i ? [" ", link] : [link])));
}

function showExperiment(experiment) {
  document.getElementById("experiment-title").textContent = experiment.name;
  const status = document.getElementById("experiment-status");
  status.textContent = experiment.status;
  status.className = `badge ${experiment.status}`;
  const progress = experiment.progress;
  fill("experiment-facts", [
    el("span", {}, "experiment ", el("b", {}, String(experiment.id))),
    el("span", {}, "runs ", el("b", {}, String(experiment.runs_total))),
    el("span", {}, progressBar(progress.fraction), ` ${progress.generations_done}/${progress.generations_total} generations`),
  ]);
}

function interval(value) {
  if (!value || value.mean === null) return "–";
  if (value.low === null) return `${fmt(value.mean)} (n = ${value.n})`;
  return `${fmt(value.mean)} [${fmt(value.low)}, ${fmt(value.high)}] (n = ${value.n})`;
}

function runLinks(runs) {
  const links = runs.map((run) => el("a", { href: page(`runs/${run.run_id}`), title: `repetition ${run.repetition}, seed ${run.seed}, ${run.status}`, class: `run-link ${run.status}` }, `run ${run.run_id}`));
  return el("span", { class: "run-links" }, links.flatMap((link, i) => (i ? [" ", link] : [link])));
}

function drawTreatments(treatments) {
  const rows = treatments.map((t) => [
    el("span", {}, el("span", { class: "swatch", style: `background:${t.color}` }), t.name),
    t.schedule,
    t.stiffness_mpa,
    t.model,
    t.runs.length,
    t.display_generation ?? "–",
    interval(t.best_distance),
    runLinks(t.runs),
  ]);
  fill("treatments", table(["treatment", "schedule", "stiffness (MPa)", "physics model", "runs", "shown at generation", "best distance [95% CI]", "runs"], rows, [2, 4, 5]));
}

function switchLines(treatments) {
  return treatments.filter((t) => t.switch_at !== null).map((t) => ({
    type: "line", xref: "x", yref: "paper", x0: t.switch_at - 0.5, x1: t.switch_at - 0.5, y0: 0, y1: 1,
    line: { color: t.color, width: 1.5, dash: "dash" },
  }));
}

/** The panel of a world: its own name, or one panel for the compound worlds of a gradual
 * switch (land>water@0.250, ...). */
function panelOf(environment) {
  return environment.includes(">") ? "during a gradual switch" : environment;
}

/** Panels of the fitness plot, one per world in the order the curves meet them: distances
 * of different worlds are not comparable, so a transition's curve is split at its switch. */
function fitnessPanels(curves) {
  const panels = [];
  for (const curve of curves) {
    for (const environment of curve.environment) {
      if (!panels.includes(panelOf(environment))) panels.push(panelOf(environment));
    }
  }
  return panels.length ? panels : ["–"];
}

/** The points of `curve` in world panel `panel`: {x, mean, low, high, n}. */
function curveIn(curve, panel) {
  const keep = curve.generation.map((_, i) => panelOf(curve.environment[i]) === panel);
  const pick = (values) => values.filter((_, i) => keep[i]);
  return { x: pick(curve.generation), mean: pick(curve.mean), low: pick(curve.low), high: pick(curve.high), n: pick(curve.n) };
}

function fitnessTraces(analysis, panels) {
  const colors = Object.fromEntries(analysis.treatments.map((t) => [t.name, t.color]));
  const traces = [];
  const legended = new Set();
  for (const curve of analysis.curves) {
    const color = colors[curve.treatment];
    panels.forEach((panel, k) => {
      const part = curveIn(curve, panel);
      if (part.x.length === 0) return;
      const yaxis = k === 0 ? "y" : `y${k + 1}`;
      const banded = part.x.map((g, i) => [g, part.low[i], part.high[i]]).filter(([, low]) => low !== null);
      if (banded.length > 0) {
        traces.push({
          x: [...banded.map((b) => b[0]), ...banded.map((b) => b[0]).reverse()],
          y: [...banded.map((b) => b[2]), ...banded.map((b) => b[1]).reverse()],
          yaxis, fill: "toself", fillcolor: withAlpha(color, 0.18), line: { width: 0 }, mode: "lines",
          hoverinfo: "skip", showlegend: false, legendgroup: curve.treatment, name: `${curve.treatment} 95% CI`,
        });
      }
      traces.push({
        x: part.x, y: part.mean, yaxis, name: curve.treatment, legendgroup: curve.treatment,
        showlegend: !legended.has(curve.treatment), mode: part.x.length > 1 ? "lines" : "lines+markers",
        line: { color, width: 2 }, customdata: part.n.map((n, i) => [n, part.low[i], part.high[i]]),
        hovertemplate: `${curve.treatment} (${panel})<br>generation %{x}<br>mean best %{y:.3f}` +
          "<br>95% CI [%{customdata[1]:.3f}, %{customdata[2]:.3f}]<br>runs %{customdata[0]}<extra></extra>",
      });
      legended.add(curve.treatment);
    });
  }
  return traces;
}

const PANEL_HEIGHT = 300; // px per world panel of the fitness plot
const PANEL_GAP = 0.08; // of the plot's height, between panels

function drawFitness(analysis) {
  const panels = fitnessPanels(analysis.curves);
  const lastGeneration = Math.max(0, ...analysis.curves.flatMap((c) => c.generation));
  const div = document.getElementById("fitness");
  div.style.height = `${Math.max(460, 100 + PANEL_HEIGHT * panels.length)}px`;
  div.dataset.worlds = panels.join(",");
  const layout = {
    font: FONT, margin: { ...MARGIN, r: 10 }, hovermode: "closest", legend: LEGEND_RIGHT,
    xaxis: { title: { text: "generation" }, zeroline: false, tickformat: "d", dtick: lastGeneration <= 20 ? 1 : undefined,
      anchor: panels.length > 1 ? `y${panels.length}` : "y" }, // whole generations, never 0.25
    shapes: switchLines(analysis.treatments),
    annotations: [],
  };
  const span = (1 - PANEL_GAP * (panels.length - 1)) / panels.length;
  panels.forEach((panel, k) => {
    const top = 1 - k * (span + PANEL_GAP);
    const name = k === 0 ? "yaxis" : `yaxis${k + 1}`;
    layout[name] = {
      domain: [Math.max(0, top - span), top], rangemode: "tozero", zeroline: false,
      title: { text: `best distance, ${panel}` },
    };
    layout.annotations.push({
      xref: "paper", yref: "paper", x: 0, y: top, xanchor: "left", yanchor: "bottom", showarrow: false,
      text: `<b>${panel}</b>`, font: { size: 12, color: "#667085" },
    });
  });
  Plotly.react("fitness", fitnessTraces(analysis, panels), layout, PLOT_CONFIG);
  document.getElementById("fitness-hint").textContent =
    `Best distance of each run's population per generation: mean over the runs of each treatment, band: ${analysis.interval}` +
    " (clipped at 0: a distance is never negative). One panel per world: distances of different worlds are not " +
    "comparable, so a transition's curve continues in its new world's panel. Dashed lines: a transition's switch.";
}

/** QD score and coverage over generations (the runs' MAP-Elites archives, analysis.qd): a
 * panel each, per treatment the mean over its runs with the 95% t band where there is one. */
function drawQD(analysis) {
  const colors = Object.fromEntries(analysis.treatments.map((t) => [t.name, t.color]));
  const metrics = [...new Set(analysis.qd.map((c) => c.metric))];
  const made = metrics.map((metric) => smallPanel({ id: `qd-${metric}`, "data-metric": metric }));
  fill("qd", made.map(([figure]) => figure));
  metrics.forEach((metric, k) => {
    const curves = analysis.qd.filter((c) => c.metric === metric);
    setTitle(made[k][1], curves[0].label);
    const traces = [];
    for (const curve of curves) {
      const color = colors[curve.treatment];
      const banded = curve.generation.map((g, i) => [g, curve.low[i], curve.high[i]]).filter(([, low]) => low !== null);
      if (banded.length > 0) {
        traces.push({
          x: [...banded.map((b) => b[0]), ...banded.map((b) => b[0]).reverse()],
          y: [...banded.map((b) => b[2]), ...banded.map((b) => b[1]).reverse()],
          fill: "toself", fillcolor: withAlpha(color, 0.18), line: { width: 0 }, mode: "lines",
          hoverinfo: "skip", showlegend: false, legendgroup: curve.treatment,
        });
      }
      traces.push({
        x: curve.generation, y: curve.mean, name: curve.treatment, legendgroup: curve.treatment, showlegend: k === 0,
        mode: curve.generation.length > 1 ? "lines" : "lines+markers", line: { color, width: 2 },
        customdata: curve.n.map((n, i) => [n, curve.low[i], curve.high[i], curve.environment[i]]),
        hovertemplate: `${curve.treatment}<br>generation %{x} (%{customdata[3]})<br>mean %{y:.3f}` +
          "<br>95% CI [%{customdata[1]:.3f}, %{customdata[2]:.3f}]<br>runs %{customdata[0]}<extra></extra>",
      });
    }
    const layout = {
      font: FONT, margin: SMALL_MARGIN, hovermode: "closest", showlegend: k === 0, legend: LEGEND_RIGHT,
      xaxis: { title: { text: "generation" }, tickformat: "d", zeroline: false },
      yaxis: { rangemode: "tozero", zeroline: false, range: metric === "coverage" ? [0, 1] : undefined },
      shapes: switchLines(analysis.treatments),
    };
    Plotly.react(made[k][1], traces, layout, PLOT_CONFIG);
  });
}

/** A small plot under its own title: a title above the plot, not in it, where Plotly's
 * toolbar (top right, on hover) would cover it. Returns [figure, plot div]. */
function smallPanel(attributes) {
  const plot = el("div", { class: "small-plot", ...attributes });
  const title = el("div", { class: "small-title" });
  return [el("figure", { class: "small-panel" }, title, plot), plot];
}

function setTitle(plot, text) {
  plot.previousElementSibling.textContent = text;
}

function frontPanels(treatments) {
  const made = treatments.map((t, i) => smallPanel({ id: `front-${i}`, "data-treatment": t.name }));
  fill("fronts", made.map(([figure]) => figure));
  return made.map(([, plot]) => plot);
}

/** The final world of a schedule (land-water -> water): the fronts of one world share
 * their distance axis (distances of different worlds are not comparable). */
function finalWorld(environment) {
  return environment.split("-").pop();
}

function distanceTops(analysis) {
  const tops = {};
  analysis.fronts.forEach((front, i) => {
    const world = finalWorld(analysis.treatments[i].environment);
    tops[world] = Math.max(tops[world] ?? 1e-3, ...front.points.distance.filter((d) => d !== null));
  });
  return tops;
}

function drawFronts(analysis) {
  const panels = frontPanels(analysis.treatments);
  const tops = distanceTops(analysis);
  analysis.fronts.forEach((front, i) => {
    const color = analysis.treatments[i].color;
    const top = tops[finalWorld(analysis.treatments[i].environment)];
    const point = (p) => p.individual_id.map((id, k) => [id, p.run_id[k], p.voxel_count[k]]);
    const hover = "individual %{customdata[0]} (run %{customdata[1]})<br>distance %{y:.3f}<br>active share %{x:.3f}" +
      "<br>voxels %{customdata[2]}<extra></extra>";
    const traces = [
      { type: "scatter", mode: "markers", name: "populations", x: front.points.active_share, y: front.points.distance,
        customdata: point(front.points), hovertemplate: hover,
        marker: { color: withAlpha(color, 0.55), size: 7, line: { color: "#1d2430", width: 0.5 } } },
      { type: "scatter", mode: "lines+markers", name: "non-dominated front", x: front.front.active_share, y: front.front.distance,
        customdata: point(front.front), hovertemplate: hover, line: { color: "#1d2430", width: 1.5, shape: "hv" },
        marker: { size: 8, color: "rgba(0,0,0,0)", line: { color: "#1d2430", width: 1.2 } } },
    ];
    const sampled = front.points.individual_id.length < front.members ? ` · ${front.points.individual_id.length} of ${front.members} shown` : "";
    const layout = {
      font: FONT, margin: SMALL_MARGIN, showlegend: false, hovermode: "closest",
      xaxis: { title: { text: "active share (energy, min)" }, range: [-0.05, 1.05], zeroline: false },
      yaxis: { title: { text: "distance (max)" }, range: [0, top * 1.08] }, // one range per world
    };
    setTitle(panels[i], `${front.treatment} (generation ${front.generation ?? "–"}${sampled})`);
    Plotly.react(panels[i], traces, layout, PLOT_CONFIG);
    panels[i].on("plotly_click", (event) => {
      const clicked = event.points && event.points[0];
      if (clicked) window.location.href = page(`individuals/${clicked.customdata[0]}`);
    });
  });
}

function drawDescriptors(analysis) {
  const colors = analysis.treatments.map((t) => t.color);
  const made = analysis.descriptors.map((d) => smallPanel({ "data-metric": d.metric }));
  fill("descriptors", made.map(([figure]) => figure));
  const panels = made.map(([, plot]) => plot);
  analysis.descriptors.forEach((descriptor, i) => {
    const traces = descriptor.treatments.map((t, k) => ({
      type: "box", name: t.treatment, y: t.values, customdata: t.run_id, boxpoints: "all", jitter: 0.4, pointpos: 0,
      marker: { color: colors[k], size: 5 }, line: { color: colors[k] }, fillcolor: withAlpha(colors[k], 0.25),
      hovertemplate: `${t.treatment}<br>run %{customdata}<br>%{y:.3f}<extra></extra>`,
    }));
    const layout = {
      font: FONT, margin: { ...SMALL_MARGIN, b: 80 }, showlegend: false,
      xaxis: { tickangle: -40, tickfont: { size: 10 } },
    };
    setTitle(panels[i], `${descriptor.label} (per run)`);
    Plotly.react(panels[i], traces, layout, PLOT_CONFIG);
  });
}

function difference(row) {
  if (row.difference === null) return "";
  if (row.difference_low === null) return fmt(row.difference);
  return `${fmt(row.difference)} [${fmt(row.difference_low)}, ${fmt(row.difference_high)}]`;
}

const WRAP = (text) => el("span", { class: "wrap" }, text);

/** The table's rows: the pair and metric, then p, adjusted p, A12 and the interval (what a
 * reader looks for first, visible without scrolling), then the details. */
function statisticsRows(rows) {
  return rows.map((r) => [
    WRAP(r.a), WRAP(r.b), WRAP(r.metric_label), r.generation ?? "–", `${r.n_a} / ${r.n_b}`,
    fmt(r.p), r.p_bonferroni === null ? "–" : `${fmt(r.p_bonferroni)} (×${r.family_size})`,
    r.significance, fmt(r.A12), difference(r), fmt(r.mean_a), fmt(r.mean_b), fmt(r.detectable_A12),
    r.test, r.comparison, r.family,
  ]);
}

function drawStatistics() {
  const metric = document.getElementById("stats-metric").value;
  const family = document.getElementById("stats-family").value;
  const rows = state.analysis.statistics.filter((r) => (!metric || r.metric === metric) && (!family || r.family === family));
  fill("statistics", table(
    ["a", "b", "metric", "generation", "n (a / b)", "p", "p (Bonferroni ×k)", "sig.", "A12",
      "a − b [95% CI]", "mean a", "mean b", "detectable A12", "test", "comparison", "family"],
    statisticsRows(rows), [3, 5, 6, 8, 9, 10, 11, 12],
  ));
  document.getElementById("stats-count").textContent = `${rows.length} of ${state.analysis.statistics.length} rows`;
}

function fillChoices(id, values) {
  const select = document.getElementById(id);
  const chosen = select.value;
  select.replaceChildren(el("option", { value: "" }, "all"), ...values.map(([value, label]) => el("option", { value }, label)));
  if (values.some(([value]) => value === chosen)) select.value = chosen;
}

function wireStatistics(rows) {
  const metrics = new Map(rows.map((r) => [r.metric, r.metric_label]));
  fillChoices("stats-metric", [...metrics.entries()]);
  fillChoices("stats-family", [...new Set(rows.map((r) => r.family))].map((f) => [f, f]));
}

function showAnalysis(analysis) {
  state.analysis = analysis;
  drawTreatments(analysis.treatments);
  drawFitness(analysis);
  drawQD(analysis);
  drawFronts(analysis);
  drawDescriptors(analysis);
  wireStatistics(analysis.statistics);
  drawStatistics();
  const status = document.getElementById("analysis-status");
  status.textContent = analysis.left_out ? `Note: ${analysis.left_out}.` : "";  // runs stopped early
  status.hidden = !analysis.left_out;
  document.body.dataset.analysis = "ready";
}

async function refresh() {
  const experiment = await getJSON(`/experiments/${experimentId}?runs_limit=0`);
  showExperiment(experiment);
  const status = document.getElementById("analysis-status");
  try {
    showAnalysis(await getJSON(`/experiments/${experimentId}/analysis`));
  } catch (error) {
    status.hidden = false;
    status.replaceChildren(errorLine(error));
  }
  return LIVE.has(experiment.status) ? LIVE_POLL_MS : IDLE_POLL_MS;
}

function main() {
  showHealth();
  downloads();
  for (const id of ["stats-metric", "stats-family"]) {
    document.getElementById(id).addEventListener("change", () => state.analysis && drawStatistics());
  }
  const missing = plotlyMissing();
  if (missing) {
    fill("fitness", errorLine(missing));
    return;
  }
  poll(async () => {
    try {
      return await refresh();
    } catch (error) {
      fill("experiment-facts", errorLine(error));
      return LIVE_POLL_MS;
    }
  });
}

main();
