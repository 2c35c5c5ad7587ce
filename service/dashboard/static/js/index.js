// Experiments page: every experiment with its runs, polled while any run is live.
import { LIVE, badge, el, errorLine, fill, fmt, getJSON, page, poll, progressBar, root, showHealth, table } from "./api.js";

const LIVE_POLL_MS = 2000;
const IDLE_POLL_MS = 15000;

function runRow(run) {
  return [
    el("a", { href: page(`runs/${run.id}`) }, `run ${run.id}`),
    run.treatment,
    run.repetition,
    run.seed,
    badge(run.status),
    `${run.generation + 1}/${run.generations}`,
    fmt(run.best_distance),
    run.best_distance === null ? "" : el("a", { href: page(`runs/${run.id}`) }, "fitness · front"),
  ];
}

function experimentPanel(experiment) {
  const progress = experiment.progress;
  return el(
    "section",
    { class: "panel experiment", id: `experiment-${experiment.id}` },
    el(
      "h2",
      {},
      `${experiment.name}`,
      el("span", { class: "muted" }, `experiment ${experiment.id}`),
      badge(experiment.status),
      progressBar(progress.fraction),
      el("span", { class: "muted" }, `${progress.generations_done}/${progress.generations_total} generations`),
      el("a", { href: `${root}/experiments/${experiment.id}/report`, class: "muted" }, "report"),
    ),
    table(
      ["run", "treatment", "rep", "seed", "status", "generation", "best distance", ""],
      experiment.runs.map(runRow),
      [2, 3, 5, 6],
    ),
  );
}

async function refresh() {
  let experiments;
  try {
    experiments = await getJSON("/experiments?limit=1000");
  } catch (error) {
    fill("experiments", errorLine(error));
    return IDLE_POLL_MS;
  }
  if (experiments.length === 0) {
    fill("experiments", el("p", { class: "muted" }, "No experiments yet: start one with `softevo run` or POST /experiments."));
  } else {
    fill("experiments", experiments.slice().reverse().map(experimentPanel));
  }
  const live = experiments.some((e) => e.runs.some((r) => LIVE.has(r.status)));
  return live ? LIVE_POLL_MS : IDLE_POLL_MS;
}

showHealth();
poll(refresh);
