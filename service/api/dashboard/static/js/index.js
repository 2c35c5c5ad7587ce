// Experiments page: the newest experiments with a page of their runs each, polled while any
// is live. Each poll asks a bounded page (EXPERIMENTS x RUNS runs at most), not the database.
import {
  LIVE, badge, el, errorLine, fill, fmt, getJSON, keyValues, page, poll, postJSON, progressBar, root, showHealth, table,
} from "./api.js";

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

/** The plan of what the form holds (POST /plan): wall time, core-hours, database, utilisation. */
async function showPlan(event) {
  event?.preventDefault();
  const body = {
    preset: document.getElementById("plan-preset").value,
    scale: document.getElementById("plan-scale").value,
    cores: Number(document.getElementById("plan-cores").value),
  };
  fill("plan", el("p", { class: "muted" }, "Planning…"));
  try {
    const plan = await postJSON("/plan", body);
    fill("plan", keyValues([
      ["wall time", `${fmt(plan.wall_hours)} hours`],
      ["core-hours", fmt(plan.core_hours)],
      ["database", `${fmt(plan.database_bytes / 1e9)} GB`],
      ["utilisation", `${Math.round(plan.utilisation * 100)}%`],
      ["evaluations", plan.evaluations.toLocaleString()],
      ["runs", String(plan.runs)],
    ]));
  } catch (error) {
    fill("plan", errorLine(error));
  }
}

/** The form's cores start at the live worker count (2 without one). */
async function setUpPlan() {
  try {
    const health = await getJSON("/health");
    if (health.workers > 0) document.getElementById("plan-cores").value = health.workers;
  } catch {
    /* the default stays */
  }
  document.getElementById("plan-form").addEventListener("submit", showPlan);
  showPlan();
}

showHealth();
setUpPlan();
poll(refresh);
