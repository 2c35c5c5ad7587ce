// Run page: fitness curves over generations, the Pareto front and the archive of elites
// (archive.js) of a chosen generation.
// Plotly is the global from /dashboard/static/vendor/plotly.min.js (the plotly package's copy).
import { LIVE, badge, el, errorLine, fill, fmt, getJSON, page, poll, showHealth, table } from "./api.js";
import { archiveError, archiveSummary, drawArchive, wireArchiveClicks } from "./archive.js";
import { FONT, LEGEND_TOP, MARGIN, PLOT_CONFIG, withAlpha } from "./plots.js";
import { world } from "./worlds.js";

const runId = Number(document.getElementById("run").dataset.run);
const POLL_MS = 2000;
const FILL_ALPHA = 0.12; // of a world's colour (worlds.js), behind the curves

const state = { run: null, generation: -2, fronts: new Map(), archives: new Map(), shown: null };

function facts(run) {
  const s = run.treatment.settings;
  const schedule = s.switch_at ? `${s.environment} (switch at generation ${s.switch_at})` : s.environment;
  const items = [
    ["environment", schedule],
    ["stiffness", `${s.stiffness_mpa} MPa`],
    ["population", s.population],
    ["generations", s.generations],
    ["workspace", (s.workspace || []).join("×")],
    ["cycles", s.max_seconds == null ? s.cycles : `${s.cycles} (≤ ${s.max_seconds} s)`],
    ["seed", run.seed],
    ["algorithm", s.algorithm],
  ];
  const parts = items.map(([name, value]) => el("span", {}, `${name} `, el("b", {}, String(value))));
  // the best per world (distances of different worlds are not comparable), its last world's
  // last; each link opens the individual in that world
  const bests = run.best_per_world || [];
  for (const best of bests) {
    const label = bests.length > 1 ? `best in ${best.environment} ` : "best ";
    parts.push(el("span", { class: "best", "data-environment": best.environment }, label,
      el("a", { href: page(`individuals/${best.individual_id}?environment=${encodeURIComponent(best.environment)}`) },
        `individual ${best.individual_id}`),
      ` (distance ${fmt(best.distance)}, generation ${best.generation})`));
  }
  if (run.error) parts.push(el("span", { class: "error" }, run.error));
  return parts;
}

function showRun(run) {
  document.getElementById("run-title").textContent = run.treatment.name;
  fill("run-status", badge(run.status).firstChild);
  document.getElementById("run-status").className = `badge ${run.status}`;
  fill("crumb-experiment", el("a", { href: `${page("")}#experiment-${run.experiment_id}` }, `experiment ${run.experiment_id}`));
  fill("run-facts", facts(run));
}

/** Background bands per environment segment (a land-water run shows where it switched). */
function environmentBands(generations) {
  const shapes = [];
  const annotations = [];
  let start = 0;
  for (let i = 1; i <= generations.length; i++) {
    if (i < generations.length && generations[i].environment === generations[start].environment) continue;
    const environment = generations[start].environment;
    shapes.push({
      type: "rect", xref: "x", yref: "paper", x0: generations[start].generation - 0.5,
      x1: generations[i - 1].generation + 0.5, y0: 0, y1: 1, line: { width: 0 },
      fillcolor: withAlpha(world(environment).colour, FILL_ALPHA), layer: "below",
    });
    annotations.push({
      xref: "x", yref: "paper", x: generations[start].generation - 0.4, y: 1, xanchor: "left",
      yanchor: "top", text: environment, showarrow: false, font: { size: 11, color: "#667085" },
    });
    start = i;
  }
  return { shapes, annotations };
}

/** The panel of a world: its own name, or one panel for the compound worlds of a gradual
 * switch (land>water@0.250, ...). */
function panelOf(environment) {
  return environment.includes(">") ? "during a gradual switch" : environment;
}

const PANEL_HEIGHT = 260; // px per world panel when a run met several worlds
const PANEL_GAP = 0.1; // of the plot's height, between panels

/** Best and mean distance per generation; a run that met several worlds gets a panel per
 * world (distances of different worlds are not comparable: no line across the switch). */
function drawFitness(generations) {
  const panels = [...new Set(generations.map((g) => panelOf(g.environment)))];
  const div = document.getElementById("fitness");
  div.dataset.worlds = panels.join(",");
  if (panels.length > 1) div.style.height = `${100 + PANEL_HEIGHT * panels.length}px`;
  const traces = [];
  const span = (1 - PANEL_GAP * (panels.length - 1)) / Math.max(1, panels.length);
  const layout = {
    font: FONT, margin: MARGIN, hovermode: "x unified", legend: LEGEND_TOP,
    xaxis: { title: { text: "generation" }, dtick: generations.length <= 20 ? 1 : undefined, zeroline: false,
      anchor: panels.length > 1 ? `y${panels.length}` : "y" },
    yaxis: { title: { text: "distance (voxel lengths)" }, rangemode: "tozero" },
  };
  panels.forEach((panel, k) => {
    const part = generations.filter((g) => panelOf(g.environment) === panel);
    const x = part.map((g) => g.generation);
    const yaxis = k === 0 ? "y" : `y${k + 1}`;
    traces.push(
      { x, y: part.map((g) => g.best_distance), yaxis, name: "best distance", legendgroup: "best", showlegend: k === 0,
        mode: "lines+markers", line: { color: "#e8322b", width: 2.5 } },
      { x, y: part.map((g) => g.mean_distance), yaxis, name: "mean distance", legendgroup: "mean", showlegend: k === 0,
        mode: "lines+markers", line: { color: "#1f6feb", width: 2, dash: "dot" } },
    );
    if (panels.length > 1) {
      const top = 1 - k * (span + PANEL_GAP);
      layout[k === 0 ? "yaxis" : `yaxis${k + 1}`] = {
        domain: [Math.max(0, top - span), top], rangemode: "tozero",
        title: { text: `distance, ${panel}` },
      };
    }
  });
  if (panels.length > 1) {
    layout.annotations = panels.map((panel, k) => ({
      xref: "paper", yref: "paper", x: 1, y: 1 - k * (span + PANEL_GAP), xanchor: "right", yanchor: "bottom",
      showarrow: false, text: `<b>${panel}</b>`, font: { size: 12, color: world(panel).colour },
    }));
  } else {
    Object.assign(layout, environmentBands(generations));
  }
  if (generations.length === 0) layout.annotations = [{ text: "no generation stored yet", showarrow: false, xref: "paper", yref: "paper", x: 0.5, y: 0.5 }];
  Plotly.react("fitness", traces, layout, PLOT_CONFIG);
}

async function frontOf(generation) {
  const live = state.run && LIVE.has(state.run.status) && generation === state.run.generation;
  if (!live && state.fronts.has(generation)) return state.fronts.get(generation);
  const front = await getJSON(`/runs/${runId}/front?generation=${generation}`);
  state.fronts.set(generation, front);
  return front;
}

function drawFront(front) {
  const members = front.individuals;
  const maxVoxels = Math.max(1, ...members.map((m) => m.objectives.voxel_count));
  const trace = {
    type: "scatter", mode: "markers",
    x: members.map((m) => m.objectives.active_share),
    y: members.map((m) => m.objectives.distance),
    customdata: members.map((m) => [m.id, m.objectives.voxel_count, m.age]),
    hovertemplate: "individual %{customdata[0]}<br>distance %{y:.3f}<br>active share %{x:.3f}" +
      "<br>voxels %{customdata[1]}<br>age %{customdata[2]}<extra></extra>",
    marker: {
      size: members.map((m) => 9 + 17 * Math.sqrt(m.objectives.voxel_count / maxVoxels)),
      color: members.map((m) => m.objectives.voxel_count), colorscale: "Viridis", showscale: true,
      colorbar: { title: { text: "voxels" }, thickness: 12 }, line: { color: "#1d2430", width: 1 },
    },
  };
  const layout = {
    font: FONT, margin: { l: 60, r: 20, t: 10, b: 45 }, hovermode: "closest",
    xaxis: { title: { text: "active share (minimised)" }, range: [-0.05, 1.05], zeroline: false },
    yaxis: { title: { text: "distance, voxel lengths (maximised)" }, rangemode: "tozero" },
  };
  Plotly.react("front", [trace], layout, PLOT_CONFIG);
  const rows = members.map((m) => [
    el("a", { href: page(`individuals/${m.id}`) }, `individual ${m.id}`),
    m.parent_id === null ? "newcomer" : el("a", { href: page(`individuals/${m.parent_id}`) }, `${m.parent_id}`),
    m.generation_born, m.age, fmt(m.objectives.distance), fmt(m.objectives.active_share),
    m.objectives.voxel_count, m.evaluation.environment, m.evaluation.stable ? "yes" : "no",
  ]);
  fill("front-table", table(
    ["individual", "parent", "born", "age", "distance", "active share", "voxels", "environment", "stable"],
    rows, [2, 3, 4, 5, 6],
  ));
}

async function archiveOf(generation) {
  const live = state.run && LIVE.has(state.run.status) && generation === state.run.generation;
  if (!live && state.archives.has(generation)) return state.archives.get(generation);
  const archive = await getJSON(`/runs/${runId}/archive?generation=${generation}`);
  state.archives.set(generation, archive);
  return archive;
}

async function showArchive(generation) {
  try {
    const archive = await archiveOf(generation);
    if (state.shown !== generation) return;
    fill("archive-summary", archiveSummary(archive));
    drawArchive("archive", archive);
  } catch (error) {
    archiveError("archive-summary", error);
  }
}

async function showFront(generation) {
  const slider = document.getElementById("front-generation");
  slider.value = String(generation);
  document.getElementById("front-label").textContent = `generation ${generation} (0–${slider.max})`;
  state.shown = generation;
  try {
    const front = await frontOf(generation);
    if (state.shown === generation) drawFront(front);
  } catch (error) {
    fill("front-table", errorLine(error));
  }
  await showArchive(generation);
}

async function refresh() {
  const run = await getJSON(`/runs/${runId}`);
  state.run = run;
  showRun(run);
  if (run.generation !== state.generation) {
    state.generation = run.generation;
    drawFitness(await getJSON(`/runs/${runId}/generations`));
    const slider = document.getElementById("front-generation");
    slider.max = String(Math.max(0, run.generation));
    slider.disabled = run.generation < 0;
    const latest = document.getElementById("front-latest").checked;
    if (run.generation >= 0 && (latest || state.shown === null)) await showFront(run.generation);
  }
  return LIVE.has(run.status) ? POLL_MS : null;
}

function wireControls() {
  const slider = document.getElementById("front-generation");
  slider.addEventListener("input", () => {
    document.getElementById("front-latest").checked = Number(slider.value) === Number(slider.max);
    showFront(Number(slider.value));
  });
  document.getElementById("front-latest").addEventListener("change", (event) => {
    if (event.target.checked && state.generation >= 0) showFront(state.generation);
  });
}

function wireClicks() {
  // plotly attaches .on() to the div after the first draw
  document.getElementById("front").on("plotly_click", (event) => {
    const point = event.points && event.points[0];
    if (point) window.location.href = page(`individuals/${point.customdata[0]}`);
  });
}

async function main() {
  showHealth();
  wireControls();
  if (typeof Plotly === "undefined") {
    fill("fitness", errorLine(new Error("plotly.js did not load: is the plotly Python package installed?")));
    return;
  }
  Plotly.newPlot("front", [], { font: FONT, margin: { l: 60, r: 20, t: 10, b: 45 } }, PLOT_CONFIG);
  Plotly.newPlot("archive", [], { font: FONT, margin: { l: 70, r: 20, t: 10, b: 50 } }, PLOT_CONFIG);
  wireClicks();
  wireArchiveClicks("archive");
  poll(async () => {
    try {
      return await refresh();
    } catch (error) {
      fill("run-facts", errorLine(error));
      return 5 * POLL_MS;
    }
  });
}

main();
