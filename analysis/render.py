"""3-D renders of voxel robots (matplotlib ``voxels``), coloured as in the paper: active
voxels red, passive voxels cyan.

``body``: (nx, ny, nz) int array, 0 empty, 1 passive, 2 active; x, y horizontal, z up.
"""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import numpy as np  # noqa: E402
from matplotlib.axes import Axes  # noqa: E402

ACTIVE_COLOR = "#e8231f"  # red: actuated voxels
PASSIVE_COLOR = "#2fd8e8"  # cyan: passive voxels
EDGE_COLOR = "#303030"
VIEW = {"elev": 22.0, "azim": -58.0}


def crop(body: np.ndarray) -> np.ndarray:
    """``body`` cut to the bounding box of its full voxels (unchanged if empty)."""
    body = np.asarray(body)
    full = np.argwhere(body > 0)
    if full.size == 0:
        return body
    low, high = full.min(axis=0), full.max(axis=0) + 1
    return body[low[0] : high[0], low[1] : high[1], low[2] : high[2]]


def draw_body(ax: Axes, body: np.ndarray, title: str | None = None, side: int | None = None) -> None:
    """Draw ``body`` on a 3-D axes: cubes coloured by material, equal aspect, no ticks.

    ``side``: the drawn cube's edge in voxels (e.g. the workspace size, so that robots of one
    figure share a scale); None crops the body to its bounding box and fits it.
    """
    body = np.asarray(body) if side else crop(body)
    colors = np.empty(body.shape, dtype=object)
    colors[body == 2] = ACTIVE_COLOR
    colors[body == 1] = PASSIVE_COLOR
    if body.any():
        ax.voxels(body > 0, facecolors=colors, edgecolor=EDGE_COLOR, linewidth=0.3)
    side = side or (max(body.shape) if body.size else 1)
    ax.set_xlim(0, side)
    ax.set_ylim(0, side)
    ax.set_zlim(0, side)
    ax.set_box_aspect((1, 1, 1))
    ax.view_init(**VIEW)
    ax.set_axis_off()
    if title:
        ax.set_title(title, fontsize=8, pad=0)
