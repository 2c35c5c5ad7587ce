// Individual page: objectives, descriptors, lineage, genome summary, evaluations and the 3D
// replay of its evaluated motion (frames as float32 binary, decoded in frames.js).
import { el, errorLine, fill, fmt, getBinary, getJSON, keyValues, page, showHealth, table } from "./api.js";
import { decodeFrames } from "./frames.js";
import { Replay } from "./replay.js";

const root = document.getElementById("individual");
const individualId = Number(root.dataset.individual);
const MAX_FRAMES = 1000;
// every trait's label (softevo.evolution.traits), as the server wrote it into the page
const TRAIT_LABELS = JSON.parse(document.body.dataset.traits || "{}");

let replay = null;

/** The objectives of the individual's last evaluation in `environment` (the world shown):
 * a distance is read in its own world. */
function showObjectives(individual, environment) {
  const inWorld = individual.evaluations.filter((e) => e.environment === environment);
  const o = inWorld.length ? inWorld.at(-1) : individual.objectives;
  if (!o) return fill("objectives", el("p", { class: "muted" }, "not evaluated"));
  const where = inWorld.length ? ` in ${environment}` : "";
  fill("objectives", keyValues([
    [`distance${where} (voxel lengths, maximised)`, fmt(o.distance)],
    ["active share (minimised)", fmt(o.active_share)],
    ["voxels (minimised)", o.voxel_count],
  ]));
}

function showDescriptors(individual) {
  const d = individual.descriptors;
  if (!d) return fill("descriptors", el("p", { class: "muted" }, "none recorded"));
  fill("descriptors", keyValues(Object.entries(d).map(([name, value]) => [TRAIT_LABELS[name] || name, fmt(value)])));
}

/** Rows summarising one CPPN ({nodes: [id, role, activation, name], links}). */
function cppnRows(name, cppn) {
  const nodes = cppn.nodes || [];
  const hidden = nodes.filter((n) => n[1] === "hidden");
  const tally = {};
  for (const node of hidden) tally[node[2]] = (tally[node[2]] || 0) + 1;
  const activations = Object.entries(tally).map(([kind, count]) => `${kind}×${count}`).join(", ");
  return [
    [`${name} CPPN`, `${nodes.length} nodes, ${(cppn.links || []).length} links`],
    [`${name} hidden nodes`, hidden.length ? activations : "none"],
    [`${name} outputs`, nodes.filter((n) => n[1] === "output").map((n) => n[3]).join(", ")],
  ];
}

function showGenome(individual) {
  const genome = individual.genome || {};
  const phenotype = individual.phenotype || {};
  const rows = Object.entries(genome).flatMap(([name, cppn]) => cppnRows(name, cppn));
  rows.push(["actuation frequency", `${fmt(phenotype.frequency)} Hz`]);
  rows.push(["voxels removed (not connected)", fmt(phenotype.removed_voxels)]);
  rows.push(["phenotype hash", el("code", {}, String(phenotype.hash || "–").slice(0, 12))]);
  const view = keyValues(rows);
  view.querySelectorAll("td:last-child").forEach((cell) => { cell.style.whiteSpace = "normal"; });
  fill("genome", view);
}

function showEvaluations(individual) {
  fill("evaluations", table(
    ["generation", "environment", "stiffness (MPa)", "age", "distance", "active share", "voxels", "frequency (Hz)", "stable", "seconds", "error"],
    individual.evaluations.map((e) => [
      e.generation, e.environment, fmt(e.stiffness / 1e6), e.age, fmt(e.distance), fmt(e.active_share),
      e.voxel_count, fmt(e.frequency), e.stable ? "yes" : "no", fmt(e.seconds, 2), e.error || "",
    ]),
    [0, 2, 3, 4, 5, 6, 7, 9],
  ));
}

async function showLineage(individual) {
  try {
    const ancestors = await getJSON(`/individuals/${individualId}/lineage`);
    const items = ancestors.map((a) => el(
      "li", {},
      a.id === individualId ? el("b", {}, `individual ${a.id}`) : el("a", { href: page(`individuals/${a.id}`) }, `individual ${a.id}`),
      el("span", { class: "muted" }, ` born gen ${a.generation_born} · ${a.environment ?? "–"} · distance ${fmt(a.distance)}` +
        (a.parent_id === null ? " · newcomer (root)" : "")),
    ));
    const parent = individual.parent_id === null
      ? el("p", {}, "A random newcomer: no parent.")
      : el("p", {}, "Parent: ", el("a", { href: page(`individuals/${individual.parent_id}`), id: "parent-link" }, `individual ${individual.parent_id}`));
    fill("lineage", parent, el("ol", { class: "lineage", start: "0" }, items));
  } catch (error) {
    fill("lineage", errorLine(error));
  }
}

function showClock(clock) {
  const t = `t = ${clock.time.toFixed(2)} s of ${clock.end.toFixed(2)} s`;
  const where = clock.settling
    ? "settling (no actuation yet)"
    : `actuation cycle ${clock.cycle} of ${clock.cycles} · phase ${Math.round(clock.phaseDegrees)}°`;
  document.getElementById("clock").textContent = `${t} · ${where}`;
  const scrub = document.getElementById("scrub");
  if (!scrub.matches(":active")) scrub.value = String(Math.round(replay.fraction * 1000));
}

async function loadReplay(environment) {
  const status = document.getElementById("viewer-status");
  status.hidden = false;
  status.textContent = "Simulating the evaluation again to record its motion…";
  document.getElementById("play").disabled = true;
  if (replay) { replay.dispose(); replay = null; }
  const query = `environment=${encodeURIComponent(environment)}`;
  try {
    const [buffer, body] = await Promise.all([
      getBinary(`/individuals/${individualId}/frames?max_frames=${MAX_FRAMES}&${query}`),
      getJSON(`/dashboard/api/individuals/${individualId}/body?${query}`).catch(() => null),
    ]);
    const motion = decodeFrames(buffer);
    replay = new Replay(document.getElementById("viewer"), motion, body, showClock);
    replay.setSpeed(Number(document.getElementById("speed").value));
    replay.setFollow(document.getElementById("follow").checked);
    window.softevoReplay = replay; // for tests and the console
    status.hidden = true;
    document.getElementById("replay-environment").textContent =
      `${environment} · ${motion.voxelCount} voxels · ${motion.frameCount} frames`;
    const play = document.getElementById("play");
    play.disabled = false;
    play.textContent = "Play";
  } catch (error) {
    status.textContent = `No replay: ${error.message}`;
    status.classList.add("error");
  }
}

function wireReplayControls() {
  const play = document.getElementById("play");
  play.addEventListener("click", () => {
    if (!replay) return;
    if (replay.playing) replay.pause(); else replay.play();
    play.textContent = replay.playing ? "Pause" : "Play";
  });
  document.getElementById("speed").addEventListener("change", (e) => replay?.setSpeed(Number(e.target.value)));
  document.getElementById("follow").addEventListener("change", (e) => replay?.setFollow(e.target.checked));
  document.getElementById("scrub").addEventListener("input", (e) => replay?.seek(Number(e.target.value) / 1000));
  document.getElementById("environment").addEventListener("change", (e) => {
    showObjectives(state.individual, e.target.value);
    loadReplay(e.target.value);
  });
}

const state = { individual: null };

/** The world shown first: the one the link named (?environment=, as the run page's best in
 * each world links), else the individual's last. */
function environmentChoice(individual) {
  const environments = [...new Set(individual.evaluations.map((e) => e.environment))];
  const named = new URLSearchParams(window.location.search).get("environment");
  const latest = environments.length ? individual.evaluations.at(-1).environment : null;
  const shown = environments.includes(named) ? named : latest;
  if (environments.length > 1) {
    fill("environment", environments.map((env) => el("option", { value: env, selected: env === shown }, env)));
    document.getElementById("environment-choice").hidden = false;
  }
  return shown;
}

async function main() {
  showHealth();
  wireReplayControls();
  let individual;
  try {
    individual = await getJSON(`/individuals/${individualId}`);
  } catch (error) {
    fill("objectives", errorLine(error));
    return;
  }
  document.getElementById("individual-title").textContent =
    `id ${individual.id} · run ${individual.run_id}'s individual ${individual.local_id} (local id) · `
    + `born in generation ${individual.generation_born}`;
  state.individual = individual;
  const environment = environmentChoice(individual);
  showObjectives(individual, environment);
  showDescriptors(individual);
  showGenome(individual);
  showEvaluations(individual);
  showLineage(individual);
  if (environment) loadReplay(environment);
  else document.getElementById("viewer-status").textContent = "Never evaluated: nothing to replay.";
}

main();
