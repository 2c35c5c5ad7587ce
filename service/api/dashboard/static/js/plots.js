// Shared Plotly settings of the dashboard's pages. Plotly is the global from
// /dashboard/static/vendor/plotly.min.js (the plotly package's copy).
// Plotly's toolbar (the mode bar) sits in the top-right corner of each plot, above the top
// margin: legends go at the top left (LEGEND_TOP) or right of the plot, below that margin
// (LEGEND_RIGHT), never under the toolbar.

export const PLOT_CONFIG = { displaylogo: false, responsive: true };
export const FONT = { family: "system-ui, sans-serif", size: 12, color: "#1d2430" };
export const MARGIN = { l: 60, r: 20, t: 36, b: 45 };
export const LEGEND_TOP = { orientation: "h", x: 0, xanchor: "left", y: 1.02, yanchor: "bottom" };
export const LEGEND_RIGHT = { orientation: "v", x: 1.02, xanchor: "left", y: 1, yanchor: "top" };

/** "rgba(r, g, b, alpha)" of a "#rrggbb" colour. */
export function withAlpha(hex, alpha) {
  const [r, g, b] = [1, 3, 5].map((i) => parseInt(hex.slice(i, i + 2), 16));
  return `rgba(${r}, ${g}, ${b}, ${alpha})`;
}

/** An error line in place of the plots when plotly.js did not load; false if it did. */
export function plotlyMissing() {
  return typeof Plotly === "undefined" ? new Error("plotly.js did not load: is the plotly Python package installed?") : false;
}
