// Shared helpers of the dashboard pages: REST calls, DOM building, formatting, polling.
// Every URL is under the server's root path (document.body.dataset.root): nothing external.

export const root = document.body.dataset.root || "";

/** URL of a dashboard page, e.g. page("runs/3"). */
export function page(path) {
  return `${root}/dashboard/${path}`;
}

export class ApiError extends Error {}

async function request(path) {
  const response = await fetch(`${root}${path}`, { headers: { Accept: "application/json" } });
  if (!response.ok) {
    let detail = `${response.status} ${response.statusText}`;
    try {
      detail = (await response.json()).detail || detail;
    } catch {
      /* not JSON */
    }
    throw new ApiError(`GET ${path}: ${detail}`);
  }
  return response;
}

/** JSON of GET `path` (e.g. "/runs/1"); throws ApiError with the server's message. */
export async function getJSON(path) {
  return (await request(path)).json();
}

/** JSON answer of POST `path` with the JSON `body` (a read that stores nothing, e.g. /plan). */
export async function postJSON(path, body) {
  const response = await fetch(`${root}${path}`, {
    method: "POST",
    headers: { Accept: "application/json", "Content-Type": "application/json" },
    body: JSON.stringify(body),
  });
  const answer = await response.json().catch(() => ({}));
  if (!response.ok) throw new ApiError(`POST ${path}: ${answer.detail || response.status}`);
  return answer;
}

/** Bytes of GET `path` as an ArrayBuffer (binary endpoints such as frames). */
export async function getBinary(path) {
  return (await request(path)).arrayBuffer();
}

/** Element `tag` with attributes (class, href, ...; on* are listeners) and children. */
export function el(tag, attributes = {}, ...children) {
  const node = document.createElement(tag);
  for (const [name, value] of Object.entries(attributes)) {
    if (value === undefined || value === null || value === false) continue;
    if (name.startsWith("on")) node.addEventListener(name.slice(2), value);
    else if (name === "class") node.className = value;
    else node.setAttribute(name, value === true ? "" : value);
  }
  for (const child of children.flat()) {
    if (child === undefined || child === null || child === false) continue;
    node.append(child instanceof Node ? child : document.createTextNode(String(child)));
  }
  return node;
}

/** Replace the children of the element with id `id`. */
export function fill(id, ...children) {
  document.getElementById(id).replaceChildren(...children.flat(Infinity));
}

/** A number with `digits` significant decimals, "–" for null. */
export function fmt(value, digits = 3) {
  if (value === null || value === undefined) return "–";
  if (typeof value !== "number") return String(value);
  if (Number.isInteger(value)) return String(value);
  const magnitude = Math.abs(value);
  if (magnitude !== 0 && (magnitude >= 1e5 || magnitude < 1e-3)) return value.toExponential(2);
  return value.toFixed(digits);
}

export function badge(status) {
  return el("span", { class: `badge ${status}` }, status);
}

export function progressBar(fraction) {
  const percent = Math.round(Math.max(0, Math.min(1, fraction)) * 100);
  return el("span", { class: "progress", title: `${percent}%` }, el("span", { style: `width:${percent}%` }));
}

/** Table of `rows` (arrays of cells); `numeric` marks right-aligned column indices. */
export function table(headers, rows, numeric = []) {
  const cell = (tag, content, index) =>
    el(tag, { class: numeric.includes(index) ? "num" : undefined }, content);
  return el(
    "table",
    {},
    el("thead", {}, el("tr", {}, headers.map((h, i) => cell("th", h, i)))),
    el("tbody", {}, rows.map((row) => el("tr", {}, row.map((c, i) => cell("td", c, i))))),
  );
}

/** Two-column key/value table. */
export function keyValues(pairs) {
  return el("table", { class: "kv" }, el("tbody", {}, pairs.map(([k, v]) => el("tr", {}, el("td", {}, k), el("td", {}, v)))));
}

export function errorLine(error) {
  return el("p", { class: "error" }, String(error.message || error));
}

/** Call `task` now and then again after the delay (ms) it returns; null stops. */
export function poll(task) {
  const again = async () => {
    let delay = 5000;
    try {
      delay = await task();
    } catch (error) {
      console.error(error);
    }
    if (delay !== null) setTimeout(again, delay);
  };
  again();
}

export const LIVE = new Set(["pending", "running"]);

/** The header's service line from GET /health (once). */
export async function showHealth() {
  const target = document.getElementById("health");
  try {
    const health = await getJSON("/health");
    target.textContent = `${health.status} · database ${health.database} · executor ${health.executor} · ` +
      `${health.workers} worker(s) · ${health.queued} queued · coordinator ${health.coordinator ? "on" : "off"}`;
  } catch (error) {
    target.textContent = `health: ${error.message}`;
  }
}
