// The run page's MAP-Elites archive (GET /runs/{id}/archive): a heatmap of the cells of its
// first two measures, each filled cell coloured by its elite's distance, an empty cell blank;
// a click on a cell opens its elite's page (its replay in the archive's world).
// Plotly is the global from /dashboard/static/vendor/plotly.min.js.
import { el, fill, fmt, page } from "./api.js";
import { FONT, PLOT_CONFIG } from "./plots.js";

// every trait's label (softevo.evolution.traits), as the server wrote it into the page
const TRAIT_LABELS = JSON.parse(document.body.dataset.traits || "{}");

/** Cell centres of a measure: `cells` values between its bounds. */
function centres([low, high], cells) {
  return Array.from({ length: cells }, (_, k) => low + ((k + 0.5) * (high - low)) / cells);
}

/** The axis of a measure: its label, its bounds, one tick per cell edge when few. */
function axis(name, [low, high], cells) {
  const step = (high - low) / cells;
  return {
    title: { text: `${TRAIT_LABELS[name] || name} [${fmt(low)}, ${fmt(high)}]` },
    range: [low, high], zeroline: false, showgrid: false,
    tick0: low, dtick: cells <= 12 ? step : undefined, tickformat: ".3~g",
  };
}

/** The elite of a cell as the URL of its page, in the archive's world. */
export function eliteUrl(individual, environment) {
  return page(`individuals/${individual}?environment=${encodeURIComponent(environment)}`);
}

/** Draw archive `archive` into the element `id` (a one-measure archive is one row). */
export function drawArchive(id, archive) {
  const [across, up] = [archive.cells[0], archive.cells[1] || 1];
  const z = Array.from({ length: up }, () => Array(across).fill(null));
  const who = Array.from({ length: up }, () => Array(across).fill(null));
  for (const elite of archive.elites) {
    const [col, row] = [elite.cell[0], elite.cell[1] || 0];
    if (z[row][col] !== null && z[row][col] >= elite.distance) continue; // more than two measures
    z[row][col] = elite.distance;
    who[row][col] = elite.individual;
  }
  const [xName, yName] = archive.measures;
  const trace = {
    type: "heatmap", z, customdata: who, x: centres(archive.bounds[0], across),
    y: up > 1 || yName ? centres(archive.bounds[1], up) : [0],
    colorscale: "Viridis", zmin: 0, hoverongaps: false, xgap: 1, ygap: 1,
    colorbar: { title: { text: "distance" }, thickness: 12 },
    hovertemplate: `individual %{customdata}<br>distance %{z:.3f}<br>${xName} %{x:.3g}` +
      (yName ? `<br>${yName} %{y:.3g}` : "") + "<extra></extra>",
  };
  const layout = {
    font: FONT, margin: { l: 70, r: 20, t: 10, b: 50 }, hovermode: "closest",
    xaxis: axis(xName, archive.bounds[0], across),
    yaxis: yName ? axis(yName, archive.bounds[1], up) : { visible: false },
  };
  const div = document.getElementById(id);
  div.dataset.filled = String(archive.filled);
  div.dataset.environment = archive.environment;
  Plotly.react(id, [trace], layout, PLOT_CONFIG);
}

/** The line under the heatmap: the archive's world, generation, coverage and QD score. */
export function archiveSummary(archive) {
  const size = archive.cells.reduce((a, b) => a * b, 1);
  const more = archive.measures.length > 2 ? ` (the grid has ${archive.measures.length} measures: drawn are the first two)` : "";
  return el("span", {},
    `${archive.environment}, after generation ${archive.generation}: `,
    el("b", {}, `${archive.filled} of ${size} cells`), ` (coverage ${fmt(100 * archive.coverage, 1)}%), `,
    "QD score ", el("b", {}, fmt(archive.qd_score)), more);
}

/** Wire clicks on the heatmap in element `id` to the elite's page. */
export function wireArchiveClicks(id) {
  const div = document.getElementById(id);
  div.on("plotly_click", (event) => {
    const point = event.points && event.points[0];
    if (point && point.customdata !== null && point.customdata !== undefined) {
      window.location.href = eliteUrl(point.customdata, div.dataset.environment);
    }
  });
}

/** Show `error` in place of the archive's summary. */
export function archiveError(id, error) {
  fill(id, el("span", { class: "error" }, String(error.message || error)));
}
