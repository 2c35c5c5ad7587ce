"""Shape descriptors of a voxel body (paper section 2.4.1, docs/spec.md section 4).

All take ``body``: (nx, ny, nz) int array, 0 empty, >0 full (1 passive, 2 active).

- ``symmetry_index``: the global symmetry index G_SI. The body is cropped to its bounding
  box; along each axis every non-empty 2-D slice (the two other axes, in x, y, z order, as
  rows and columns) gets six shares: reflections about the vertical axis (columns
  reversed), the horizontal axis (rows reversed), the primary diagonal (transpose) and the
  secondary diagonal (anti-transpose), and translations vertical (the first half of the rows
  against the second half) and horizontal (same over columns). A non-square slice is padded
  with empty cells to a square anchored at row 0, column 0 before a diagonal reflection.
  For an odd size n the halves are the first and the last ceil(n/2) rows, so they share the
  middle row (a one-row slice compares with itself). Each share is the overlap counted as
  |A and B| / |A or B| (intersection over union; 1 when both are empty). Shares are averaged
  per axis over slices, then over the six kinds, then over the three axes. A full cube gives 1.
- ``branching_index``: 1 - V / V_hull, V the volume of the voxel surface mesh and V_hull the
  volume of its convex hull (trimesh). A full box gives 0.
- ``shape_entropy``: Shannon entropy (bits) of the discrete Gaussian curvature of the
  undeformed surface mesh, taken at every vertex of the mesh, flat ones included (docs/spec.md
  section 4: the curvature of the whole surface is the random variable, so the share of the
  surface that is angular counts). The measure at each vertex is trimesh's
  ``discrete_gaussian_curvature_measure`` over a ball of ``radius`` (default 0: the vertex's
  angle defect, 2 pi minus the angles of its faces). On a voxel mesh every defect is a
  multiple of pi/2: 0 on a flat face or a straight edge, pi/2 at a convex corner, -pi/2 at a
  reflex corner, -pi at a saddle, and so on. Bins: width pi/2, centred on k pi/2, one per
  multiple that occurs (empty bins add nothing to an entropy, so the bin count is the number
  of distinct multiples, at most (max - min) / (pi/2) + 1). A single voxel (8 corners) gives
  0 bits; a 2x1x1 bar (8 corners, 4 straight-edge vertices) gives H(8/12, 4/12) = 0.918 bits.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from softevo.evolution.genotype import Phenotype
from softevo.sim.system import largest_component

# ---- surface mesh ------------------------------------------------------------------------------
_UNIT_SQUARE = np.array([[0, 0], [1, 0], [1, 1], [0, 1]])


def _faces_for(full: np.ndarray, axis: int, sign: int) -> tuple[np.ndarray, np.ndarray]:
    """Quads of the exposed faces of ``full`` facing (axis, sign): corners (q, 4, 3) int."""
    padded = np.pad(full, 1)
    neighbour = np.roll(padded, -sign, axis=axis)[1:-1, 1:-1, 1:-1]
    voxels = np.argwhere(full & ~neighbour)  # (q, 3)
    b, c = (axis + 1) % 3, (axis + 2) % 3  # e_b x e_c = e_axis
    square = _UNIT_SQUARE if sign > 0 else _UNIT_SQUARE[::-1]
    corners = np.repeat(voxels[:, None, :], 4, axis=1)
    corners[:, :, axis] += 1 if sign > 0 else 0
    corners[:, :, b] += square[:, 0]
    corners[:, :, c] += square[:, 1]
    return corners, np.full(len(voxels), 2 * axis + (sign < 0))


def surface_mesh(body: np.ndarray, pitch: float = 1.0):
    """The voxel body's outer surface as a ``trimesh.Trimesh`` (only faces between a full
    voxel and an empty cell or the outside, two triangles each, outward normals), vertices
    merged, in units of ``pitch``. Also returns each face's normal code (axis*2 + negative),
    shape (n_faces,)."""
    import trimesh

    full = np.asarray(body) > 0
    quads, codes = zip(*(_faces_for(full, a, s) for a in range(3) for s in (1, -1)), strict=True)
    quads, codes = np.concatenate(quads), np.concatenate(codes)
    vertices, inverse = np.unique(quads.reshape(-1, 3), axis=0, return_inverse=True)
    corners = inverse.reshape(-1, 4)
    triangles = np.concatenate([corners[:, [0, 1, 2]], corners[:, [0, 2, 3]]])
    mesh = trimesh.Trimesh(vertices * pitch, triangles, process=False)
    return mesh, np.concatenate([codes, codes])


# ---- descriptors --------------------------------------------------------------------------------
def _share(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Intersection over union per slice of (n, r, c) bool stacks; 1 where both are empty."""
    inter = (a & b).sum(axis=(1, 2))
    union = (a | b).sum(axis=(1, 2))
    return np.where(union > 0, inter / np.maximum(union, 1), 1.0)


def slice_symmetry(slices: np.ndarray) -> np.ndarray:
    """The six shares (r_v, r_h, r_pd, r_sd, t_v, t_h) of each slice: (n, r, c) -> (n, 6)."""
    slices = np.asarray(slices, dtype=bool)
    n, rows, cols = slices.shape
    side = max(rows, cols)
    square = np.zeros((n, side, side), dtype=bool)
    square[:, :rows, :cols] = slices
    half_r, half_c = -(-rows // 2), -(-cols // 2)
    return np.stack(
        [
            _share(slices, slices[:, :, ::-1]),
            _share(slices, slices[:, ::-1, :]),
            _share(square, square.transpose(0, 2, 1)),
            _share(square, square[:, ::-1, ::-1].transpose(0, 2, 1)),
            _share(slices[:, :half_r, :], slices[:, rows - half_r :, :]),
            _share(slices[:, :, :half_c], slices[:, :, cols - half_c :]),
        ],
        axis=1,
    )


def bounding_box(body: np.ndarray) -> np.ndarray:
    """``body`` cropped to the bounding box of its full voxels."""
    full = np.argwhere(np.asarray(body) > 0)
    low, high = full.min(axis=0), full.max(axis=0) + 1
    return np.asarray(body)[low[0] : high[0], low[1] : high[1], low[2] : high[2]]


def symmetry_axes(body: np.ndarray) -> np.ndarray:
    """Per-axis symmetry shares, shape (3, 6): rows x, y, z; columns as ``slice_symmetry``."""
    box = bounding_box(body) > 0
    per_axis = []
    for axis in range(3):
        slices = np.moveaxis(box, axis, 0)
        slices = slices[slices.any(axis=(1, 2))]
        per_axis.append(slice_symmetry(slices).mean(axis=0))
    return np.array(per_axis)


def symmetry_index(body: np.ndarray) -> float:
    """Global symmetry index G_SI in [0, 1] (1 for a full box with equal sides)."""
    return float(symmetry_axes(body).mean())


def branching_index(body: np.ndarray) -> float:
    """BI = 1 - V / V_hull in [0, 1)."""
    mesh, _ = surface_mesh(body)
    return float(max(0.0, 1.0 - mesh.volume / mesh.convex_hull.volume))


def surface_curvature(body: np.ndarray, radius: float = 0.0) -> np.ndarray:
    """Discrete Gaussian curvature measure (radians) at every vertex of the surface mesh,
    flat and straight-edge vertices included, shape (n_vertices,); radius in voxel lengths."""
    import trimesh

    mesh, _ = surface_mesh(body)
    return trimesh.curvature.discrete_gaussian_curvature_measure(mesh, mesh.vertices, radius)


def shape_entropy(body: np.ndarray, radius: float = 0.0) -> float:
    """Shannon entropy (bits) of the surface curvature binned by multiples of pi/2."""
    curvature = surface_curvature(body, radius)
    if curvature.size == 0:
        return 0.0
    _, counts = np.unique(np.round(curvature / (np.pi / 2)).astype(int), return_counts=True)
    p = counts / counts.sum()
    return float(max(0.0, -(p * np.log2(p)).sum()))


def _voxel_array(body: Any) -> np.ndarray:
    """``body`` as an array, or ValueError saying what a body is (not NumPy's own words)."""
    try:
        array = np.asarray(body)
    except ValueError:  # ragged nested lists
        array = np.asarray(None)
    if array.dtype.kind not in "biuf" or array.ndim != 3 or not np.isin(array, (0, 1, 2)).all():
        shown = repr(body) if len(repr(body)) <= 40 else f"{repr(body)[:37]}..."
        raise ValueError(f"body must be a 3-D array body[x][y][z] of 0 (empty), 1 (passive) "
                         f"and 2 (active) (got {shown})")
    return array


def describe(body: np.ndarray, frequency: float | None = None) -> dict[str, Any]:
    """All descriptors of a body's largest face-connected component (what gets simulated).

    Keys: symmetry, branching, shape_entropy, voxel_count, active_share (+ frequency in Hz
    when given). An empty body gives voxel_count 0 and the shape descriptors as None.
    ValueError for anything but a 3-D array of 0 (empty), 1 (passive) and 2 (active).
    """
    body = _voxel_array(body)
    kept = np.where(largest_component(body > 0), body, 0)
    count = int(np.count_nonzero(kept))
    result: dict[str, Any] = {
        "symmetry": symmetry_index(kept) if count else None,
        "branching": branching_index(kept) if count else None,
        "shape_entropy": shape_entropy(kept) if count else None,
        "voxel_count": count,
        "active_share": float(np.count_nonzero(kept == 2)) / count if count else 0.0,
    }
    if frequency is not None:
        result["frequency"] = float(frequency)
    return result


def describe_phenotype(phenotype: Phenotype) -> dict[str, Any]:
    """``describe`` of a phenotype's body, with its frequency."""
    return describe(phenotype.body, phenotype.frequency)
