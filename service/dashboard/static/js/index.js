// Experiments page: the newest experiments with a page of their runs each, polled while any
// is live. Each poll asks a bounded page (EXPERIMENTS x RUNS runs at most), not the database.
import { LIVE, badge, el, errorLine, fill, fmt, getJSON, page, poll, progressBar, root, showHealth, table } from "./api.js";

const LIVE_POLL_MS = 2000;
const IDLE_POLL_MS = 15000;
const EXPERIMENTS = 20; // newest experiments shown
const RUNS = 50; // runs shown per experiment (the counts and progress cover them all)

/** "land 5.21 · water 0.651": the best distance reached in each world, in the order met. */
function bestPerWorld(worlds) {
  const entries = Object.entries(worlds ?? {});
  return entries.length === 0 ? "–" : entries.map(([world, best]) => `${world} ${fmt(best)}`).join(" · ");
}

function runRow(run) {
  return [
    el("a", { href: page(`runs/${run.id}`) }, `run ${run.id}`),
    run.treatment,
    run.repetition,
    run.seed,
    badge(run.status),
    `${run.generation + 1}/${run.generations}`,
    run.environment ?? "–",
    fmt(run.best_distance),
    bestPerWorld(run.best_by_world),
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
      el("a", { href: page(`experiments/${experiment.id}`), class: "experiment-link" }, experiment.name),
      el("span", { class: "muted" }, `experiment ${experiment.id}`),
      badge(experiment.status),
      progressBar(progress.fraction),
      el("span", { class: "muted" }, `${progress.generations_done}/${progress.generations_total} generations`),
      el("a", { href: page(`experiments/${experiment.id}`), class: "muted" }, "compare treatments"),
      el("a", { href: `${root}/experiments/${experiment.id}/report`, class: "muted" }, "report"),
    ),
    table(
      ["run", "treatment", "rep", "seed", "status", "generation", "world", "best (last gen)", "best per world", ""],
      experiment.runs.map(runRow),
      [2, 3, 5, 7],
    ),
    experiment.runs_total > experiment.runs.length
      ? el("p", { class: "muted" }, `the first ${experiment.runs.length} of ${experiment.runs_total} runs`)
      : null,
  );
}

async function refresh() {
  let experiments;
  try {
    experiments = await getJSON(`/experiments?limit=${EXPERIMENTS}&runs_limit=${RUNS}&newest_first=true`);
  } catch (error) {
    fill("experiments", errorLine(error));
    return IDLE_POLL_MS;
  }
  if (experiments.length === 0) {
    fill("experiments", el("p", { class: "muted" }, "No experiments yet: start one with `softevo run` or POST /experiments."));
  } else {
    fill("experiments", experiments.map(experimentPanel));
  }
  const live = experiments.some((e) => LIVE.has(e.status));
  return live ? LIVE_POLL_MS : IDLE_POLL_MS;
}

showHealth();
poll(refresh);
