// The world registry (softevo.sim.worlds), as the server wrote it into the page
// (body data-worlds, the same list as GET /worlds): every world's colours and physics.
// No world is named here: a world registered on the server is drawn with its own colours.

const WORLDS = Object.fromEntries(JSON.parse(document.body.dataset.worlds || "[]").map((w) => [w.name, w]));
const UNKNOWN = { colour: "#667085", background: "#eef2f6", floor: true };

/** The registry's record of `name` (a neutral grey one for a name the server did not list). */
export function world(name) {
  return WORLDS[name] || UNKNOWN;
}

/** [r, g, b] (0..255) of a world's colour. */
export function worldRGB(name) {
  const hex = world(name).colour.replace("#", "");
  return [0, 2, 4].map((i) => parseInt(hex.slice(i, i + 2), 16));
}

/** The first world of the registry: the default of a page that does not know the world. */
export function defaultWorld() {
  return Object.keys(WORLDS)[0];
}
