// Phylogeny tree of a run: the nodes the server picked (GET /dashboard/api/runs/{id}/tree:
// surviving lineages and a bounded sample of extinct ones) laid out and drawn on a canvas.
// x: generation; y: leaves in depth-first order, a parent at the mean of its children.
import { el, errorLine, fill, fmt, getJSON, page, showHealth } from "./api.js";
import { worldRGB as pureRGB } from "./worlds.js";

const runId = Number(document.getElementById("tree-page").dataset.run);
const HEIGHT = 560;
const MARGIN = { left: 80, right: 18, top: 26, bottom: 34 }; // left: the y axis labels
const UNKNOWN_RGB = [120, 120, 120];
const HIT_PX = 8;
const Y_LABEL = "lineages (a row per line of descent)";

/** [r, g, b] of a world name; a compound world "a>b@s" mixes a and b by s. */
function worldRGB(name) {
  if (!name) return UNKNOWN_RGB;
  const compound = /^(\w+)>(\w+)@([0-9.]+)$/.exec(name);
  if (!compound) return pureRGB(name);
  const [a, b, s] = [pureRGB(compound[1]), pureRGB(compound[2]), Number(compound[3])];
  return a.map((value, i) => Math.round(value * (1 - s) + b[i] * s));
}

function rgba(rgb, alpha) {
  return `rgba(${rgb[0]}, ${rgb[1]}, ${rgb[2]}, ${alpha})`;
}

/** y (in leaf units) of every node: leaves numbered depth-first, parents at their children's mean. */
function layout(nodes) {
  const byId = new Map(nodes.map((n) => [n.id, n]));
  const children = new Map();
  const roots = [];
  for (const node of nodes) {
    if (node.parent_id !== null && byId.has(node.parent_id)) {
      if (!children.has(node.parent_id)) children.set(node.parent_id, []);
      children.get(node.parent_id).push(node);
    } else {
      roots.push(node);
    }
  }
  // by birth within a tree; extinct roots scattered (by a hash of the id) so a sample spread
  // over thousands of generations does not stack into one diagonal
  const order = (a, b) => (a.generation_born - b.generation_born) || (a.id - b.id);
  const scatter = (node) => (node.id * 7919) % 10007;
  roots.sort((a, b) => (a.surviving ? order(a, b) : scatter(a) - scatter(b) || a.id - b.id));
  for (const list of children.values()) list.sort(order);
  let leaves = 0;
  const y = new Map();
  for (const root of roots) {
    const stack = [[root, false]];
    while (stack.length) {
      const [node, expanded] = stack.pop();
      const kids = children.get(node.id) || [];
      if (!kids.length) {
        y.set(node.id, leaves++);
      } else if (expanded) {
        y.set(node.id, kids.reduce((sum, kid) => sum + y.get(kid.id), 0) / kids.length);
      } else {
        stack.push([node, true]);
        for (let i = kids.length - 1; i >= 0; i--) stack.push([kids[i], false]);
      }
    }
  }
  return { y, leaves, byId };
}

function draw(canvas, tree) {
  const started = performance.now();
  const dpr = window.devicePixelRatio || 1;
  const width = canvas.clientWidth || 1200;
  canvas.width = Math.round(width * dpr);
  canvas.height = Math.round(HEIGHT * dpr);
  canvas.style.height = `${HEIGHT}px`;
  const ctx = canvas.getContext("2d");
  ctx.scale(dpr, dpr);
  ctx.fillStyle = "#ffffff";
  ctx.fillRect(0, 0, width, HEIGHT);
  // surviving lineages in the upper band, the extinct sample below (each laid out on its own)
  const alive = layout(tree.nodes.filter((n) => n.surviving));
  const dead = layout(tree.nodes.filter((n) => !n.surviving));
  const byId = new Map([...alive.byId, ...dead.byId]);
  const span = HEIGHT - MARGIN.top - MARGIN.bottom;
  const split = dead.leaves ? (alive.leaves ? 0.6 : 0) : 1;
  const band = (part, top, size) => (row) => top + (part.leaves > 1 ? row / (part.leaves - 1) : 0.5) * size;
  const rowOf = {
    true: band(alive, MARGIN.top, span * split - (split < 1 ? 12 : 0)),
    false: band(dead, MARGIN.top + span * split + (split > 0 ? 12 : 0), span * (1 - split) - (split > 0 ? 12 : 0)),
  };
  const y = new Map([...alive.y].map(([id, row]) => [id, rowOf.true(row)]).concat(
    [...dead.y].map(([id, row]) => [id, rowOf.false(row)])));
  const py = (value) => value;
  const lastGeneration = Math.max(1, tree.generation);
  const px = (g) => MARGIN.left + (g / lastGeneration) * (width - MARGIN.left - MARGIN.right);
  // axis and the switch
  ctx.strokeStyle = "#dde2ea";
  ctx.fillStyle = "#667085";
  ctx.font = "12px system-ui, sans-serif";
  ctx.lineWidth = 1;
  ctx.textAlign = "center";
  for (const g of generationTicks(lastGeneration)) {
    ctx.beginPath(); ctx.moveTo(px(g), MARGIN.top - 6); ctx.lineTo(px(g), HEIGHT - MARGIN.bottom); ctx.stroke();
    ctx.fillText(String(g), px(g), HEIGHT - MARGIN.bottom + 14);
  }
  ctx.fillText("generation", MARGIN.left + (width - MARGIN.left - MARGIN.right) / 2, HEIGHT - 3);
  ctx.textAlign = "left";
  yAxisLabels(ctx, rowOf, alive, dead, split, span);
  if (tree.switch_at !== null) {
    if (tree.switch_over > 0) {
      ctx.fillStyle = "rgba(130, 90, 200, 0.10)";
      ctx.fillRect(px(tree.switch_at), MARGIN.top - 6, px(tree.arrival) - px(tree.switch_at), HEIGHT - MARGIN.top - MARGIN.bottom + 6);
    }
    ctx.strokeStyle = "#7a4cc2";
    ctx.setLineDash([6, 4]);
    ctx.lineWidth = 1.5;
    ctx.beginPath(); ctx.moveTo(px(tree.switch_at), MARGIN.top - 10); ctx.lineTo(px(tree.switch_at), HEIGHT - MARGIN.bottom); ctx.stroke();
    ctx.setLineDash([]);
    ctx.fillStyle = "#7a4cc2";
    ctx.fillText(`switch ${tree.environments.join(" → ")} at ${tree.switch_at}`, px(tree.switch_at) + 4, MARGIN.top - 12);
  }
  const placed = [];
  for (const surviving of [false, true]) {
    for (const node of tree.nodes) {
      if (node.surviving !== surviving) continue;
      const x = px(node.generation_born), yy = py(y.get(node.id));
      const rgb = worldRGB(node.environment);
      ctx.strokeStyle = rgba(surviving ? rgb.map((c) => Math.round(c * 0.75)) : rgb, surviving ? 0.95 : 0.35);
      ctx.lineWidth = surviving ? 2 : 1;
      const parent = node.parent_id !== null ? byId.get(node.parent_id) : undefined;
      ctx.beginPath();
      if (parent) {
        ctx.moveTo(px(parent.generation_born), py(y.get(parent.id)));
        ctx.lineTo(x, yy);
      } else if (node.parent_generation !== null && node.parent_generation !== undefined) {
        ctx.moveTo(px(node.parent_generation), yy);
        ctx.lineTo(x, yy);
      }
      if (node.last_generation !== null && node.last_generation > node.generation_born) {
        ctx.moveTo(x, yy);
        ctx.lineTo(px(node.last_generation), yy);
      }
      ctx.stroke();
      ctx.fillStyle = rgba(rgb, surviving ? 1 : 0.5);
      ctx.beginPath();
      ctx.arc(x, yy, surviving ? 3 : 1.8, 0, 2 * Math.PI);
      ctx.fill();
      placed.push({ id: node.id, x, y: yy, surviving, environment: node.environment, node });
    }
  }
  return { placed, ms: performance.now() - started };
}

/** Generations 0..last at a round step (1, 2 or 5 x 10^k), at most about 10 of them. */
function generationTicks(last) {
  const rough = Math.max(1, last / 10);
  const power = 10 ** Math.floor(Math.log10(rough));
  const step = [1, 2, 5, 10].map((m) => m * power).find((s) => s >= rough);
  const ticks = [];
  for (let g = 0; g <= last; g += step) ticks.push(g);
  return ticks;
}

/** The y axis: what a row is (one per lineage's leaf, parents between their children), and
 * which band holds the surviving lineages and which the extinct sample. */
function yAxisLabels(ctx, rowOf, alive, dead, split, span) {
  ctx.save();
  ctx.fillStyle = "#667085";
  ctx.font = "12px system-ui, sans-serif";
  ctx.translate(14, MARGIN.top + span / 2);
  ctx.rotate(-Math.PI / 2);
  ctx.textAlign = "center";
  ctx.fillText(Y_LABEL, 0, 0);
  ctx.restore();
  ctx.save();
  ctx.fillStyle = "#667085";
  ctx.font = "11px system-ui, sans-serif";
  ctx.textAlign = "right";
  ctx.textBaseline = "middle";
  if (alive.leaves) ctx.fillText("surviving", MARGIN.left - 4, (rowOf.true(0) + rowOf.true(alive.leaves - 1)) / 2);
  if (dead.leaves && split < 1) ctx.fillText("extinct", MARGIN.left - 4, (rowOf.false(0) + rowOf.false(dead.leaves - 1)) / 2);
  ctx.restore();
}

function nearest(placed, x, y) {
  let best = null, bestDistance = HIT_PX * HIT_PX;
  for (const p of placed) {
    const d = (p.x - x) ** 2 + (p.y - y) ** 2;
    if (d <= bestDistance) { best = p; bestDistance = d; }
  }
  return best;
}

function legend(tree) {
  const worlds = new Set(tree.nodes.map((n) => n.environment).filter(Boolean));
  const swatch = (name) => el("span", { style: `display:inline-block;width:12px;height:12px;border-radius:6px;margin:0 4px 0 12px;vertical-align:-2px;background:${rgba(worldRGB(name), 1)}` });
  return [...worlds].sort().map((name) => [swatch(name), name]);
}

async function main() {
  showHealth();
  const canvas = document.getElementById("tree");
  try {
    const [run, tree] = await Promise.all([getJSON(`/runs/${runId}`), getJSON(`/dashboard/api/runs/${runId}/tree`)]);
    document.getElementById("tree-title").textContent = run.treatment.name;
    const survivors = tree.nodes.filter((n) => n.surviving).length;
    fill("tree-facts",
      el("span", {}, "last generation ", el("b", {}, String(tree.generation))),
      el("span", {}, "surviving lineage nodes ", el("b", { id: "tree-survivors" }, `${survivors} of ${tree.survivors_total}`)),
      el("span", {}, "extinct shown ", el("b", { id: "tree-extinct" }, `${tree.nodes.length - survivors} of ${tree.extinct_total}`)),
      tree.switch_at === null ? el("span", {}, "no environment switch") :
        el("span", {}, "switch at ", el("b", {}, String(tree.switch_at)),
          tree.switch_over ? ` (gradual over ${tree.switch_over}, wholly in ${tree.environments[1]} from ${tree.arrival})` : ""),
    );
    fill("tree-legend", legend(tree));
    let drawn = draw(canvas, tree);
    const publish = () => {
      window.softevoTree = {
        ms: drawn.ms, drawn: drawn.placed.length, survivors, switch_at: tree.switch_at,
        nodes: drawn.placed.map(({ id, x, y, surviving, environment }) => ({ id, x, y, surviving, environment })),
      };
    };
    publish();
    window.addEventListener("resize", () => { drawn = draw(canvas, tree); publish(); });
    const at = (event) => {
      const box = canvas.getBoundingClientRect();
      return nearest(drawn.placed, event.clientX - box.left, event.clientY - box.top);
    };
    canvas.addEventListener("mousemove", (event) => {
      const hit = at(event);
      document.getElementById("tree-hover").textContent = hit
        ? `individual ${hit.id}: born ${hit.node.generation_born}, kept to ${hit.node.last_generation ?? "–"}, ` +
          `${hit.node.environment ?? "?"}, distance ${fmt(hit.node.distance)}${hit.surviving ? " · surviving lineage" : ""}`
        : "\u00a0";
    });
    canvas.addEventListener("click", (event) => {
      const hit = at(event);
      if (hit) window.location.href = page(`individuals/${hit.id}`);
    });
  } catch (error) {
    fill("tree-facts", errorLine(error));
  }
}

main();
