// Experiment page: the treatments side by side, from GET /experiments/{id}/analysis
// (service.reports.report.experiment): fitness curves with 95% intervals over runs, aggregated
// Pareto fronts, descriptor distributions, the statistics table with families, every run,
// and the downloads (GET /experiments/{id}/export). Polled while a run is live.
import { LIVE, el, errorLine, fill, fmt, getJSON, page, poll, progressBar, root, showHealth, table } from "./api.js";
import { FONT, LEGEND_RIGHT, MARGIN, PLOT_CONFIG, plotlyMissing, withAlpha } from "./plots.js";

const experimentId = Number(document.getElementById("experiment").dataset.experiment);
const LIVE_POLL_MS = 30000; // the analysis is an expensive read: recomputed once per change at most
const IDLE_POLL_MS = null;
const TABLES = ["runs", "individuals", "populations"];
const FORMATS = ["csv", "parquet"];
const SMALL_MARGIN = { l: 50, r: 10, t: 36, b: 40 };

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

function drawFitness(analysis) {
  const colors = Object.fromEntries(analysis.treatments.map((t) => [t.name, t.color]));
  const traces = [];
  for (const curve of analysis.curves) {
    const color = colors[curve.treatment];
    const banded = curve.generation.map((g, i) => [g, curve.low[i], curve.high[i]]).filter(([, low]) => low !== null);
    if (banded.length > 0) {
      traces.push({
        x: [...banded.map((b) => b[0]), ...banded.map((b) => b[0]).reverse()],
        y: [...banded.map((b) => b[2]), ...banded.map((b) => b[1]).reverse()],
        fill: "toself", fillcolor: withAlpha(color, 0.18), line: { width: 0 }, mode: "lines",
        hoverinfo: "skip", showlegend: false, legendgroup: curve.treatment, name: `${curve.treatment} 95% CI`,
      });
    }
    traces.push({
      x: curve.generation, y: curve.mean, name: curve.treatment, legendgroup: curve.treatment, mode: "lines",
      line: { color, width: 2 }, customdata: curve.n.map((n, i) => [n, curve.low[i], curve.high[i]]),
      hovertemplate: `${curve.treatment}<br>generation %{x}<br>mean best %{y:.3f}` +
        "<br>95% CI [%{customdata[1]:.3f}, %{customdata[2]:.3f}]<br>runs %{customdata[0]}<extra></extra>",
    });
  }
  const layout = {
    font: FONT, margin: { ...MARGIN, r: 10 }, hovermode: "closest", legend: LEGEND_RIGHT,
    xaxis: { title: { text: "generation" }, zeroline: false },
    yaxis: { title: { text: "best distance (voxel lengths)" }, rangemode: "tozero" },
    shapes: switchLines(analysis.treatments),
  };
  Plotly.react("fitness", traces, layout, PLOT_CONFIG);
  document.getElementById("fitness-hint").textContent =
    `Best distance of each run's population per generation: mean over the runs of each treatment, band: ${analysis.interval}. ` +
    "Dashed lines: a transition's switch.";
}

function frontPanels(treatments) {
  const panels = treatments.map((t, i) => el("div", { class: "small-plot", id: `front-${i}`, "data-treatment": t.name }));
  fill("fronts", panels);
  return panels;
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
      title: { text: `${front.treatment} (generation ${front.generation ?? "–"}${sampled})`, font: { size: 12 }, x: 0, xanchor: "left" },
      xaxis: { title: { text: "active share (energy, min)" }, range: [-0.05, 1.05], zeroline: false },
      yaxis: { title: { text: "distance (max)" }, range: [0, top * 1.08] }, // one range per world
    };
    Plotly.react(panels[i], traces, layout, PLOT_CONFIG);
    panels[i].on("plotly_click", (event) => {
      const clicked = event.points && event.points[0];
      if (clicked) window.location.href = page(`individuals/${clicked.customdata[0]}`);
    });
  });
}

function drawDescriptors(analysis) {
  const colors = analysis.treatments.map((t) => t.color);
  const panels = analysis.descriptors.map((d) => el("div", { class: "small-plot", "data-metric": d.metric }));
  fill("descriptors", panels);
  analysis.descriptors.forEach((descriptor, i) => {
    const traces = descriptor.treatments.map((t, k) => ({
      type: "box", name: t.treatment, y: t.values, customdata: t.run_id, boxpoints: "all", jitter: 0.4, pointpos: 0,
      marker: { color: colors[k], size: 5 }, line: { color: colors[k] }, fillcolor: withAlpha(colors[k], 0.25),
      hovertemplate: `${t.treatment}<br>run %{customdata}<br>%{y:.3f}<extra></extra>`,
    }));
    const layout = {
      font: FONT, margin: { ...SMALL_MARGIN, b: 80 }, showlegend: false,
      title: { text: `${descriptor.label} (per run)`, font: { size: 12 }, x: 0, xanchor: "left" },
      xaxis: { tickangle: -40, tickfont: { size: 10 } },
    };
    Plotly.react(panels[i], traces, layout, PLOT_CONFIG);
  });
}

function difference(row) {
  if (row.difference === null) return "";
  if (row.difference_low === null) return fmt(row.difference);
  return `${fmt(row.difference)} [${fmt(row.difference_low)}, ${fmt(row.difference_high)}]`;
}

function statisticsRows(rows) {
  return rows.map((r) => [
    r.family, r.comparison, r.metric_label, r.a, r.b, r.generation ?? "–", r.test, `${r.n_a} / ${r.n_b}`,
    fmt(r.mean_a), fmt(r.mean_b), fmt(r.p), r.p_bonferroni === null ? "–" : `${fmt(r.p_bonferroni)} (×${r.family_size})`,
    r.significance, fmt(r.A12), fmt(r.detectable_A12), difference(r),
  ]);
}

function drawStatistics() {
  const metric = document.getElementById("stats-metric").value;
  const family = document.getElementById("stats-family").value;
  const rows = state.analysis.statistics.filter((r) => (!metric || r.metric === metric) && (!family || r.family === family));
  fill("statistics", table(
    ["family", "comparison", "metric", "a", "b", "generation", "test", "n (a / b)", "mean a", "mean b", "p",
      "p (Bonferroni, family size)", "sig.", "A12", "detectable A12", "a − b [95% CI]"],
    statisticsRows(rows), [5, 8, 9, 10, 11, 13, 14],
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
