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
  volume of its convex hull. A full box gives 0.
- ``shape_entropy``: Shannon entropy (bits) of the discrete Gaussian curvature of the
  undeformed surface mesh, taken at every vertex of the mesh, flat ones included (docs/spec.md
  section 4: the curvature of the whole surface is the random variable, so the share of the
  surface that is angular counts). The measure at each vertex is the discrete Gaussian
  curvature measure over a ball of ``radius`` (default 0: the vertex's angle defect, 2 pi
  minus the angles of its faces). On a voxel mesh every defect is a multiple of pi/2: 0 on a
  flat face or a straight edge, pi/2 at a convex corner, -pi/2 at a reflex corner, -pi at a
  saddle, and so on. Bins: width pi/2, centred on k pi/2, one per multiple that occurs (empty
  bins add nothing to an entropy, so the bin count is the number of distinct multiples, at
  most (max - min) / (pi/2) + 1). A single voxel (8 corners) gives 0 bits; a 2x1x1 bar (8
  corners, 4 straight-edge vertices) gives H(8/12, 4/12) = 0.918 bits.

The surface mesh is the body's exposed unit squares (faces between a full voxel and an empty
cell or the outside), each split into two right triangles, its vertices the lattice corners
merged by position. Nothing here builds it: every quantity above is counted on the lattice
(tests/evolution/test_descriptors_reference.py checks each against the mesh and trimesh).
- V is the number of full voxels: the mesh is closed and its faces point away from the full
  voxels (those of a cavity too), so its enclosed volume is exactly the voxels'.
- A lattice corner touched by n exposed squares has angles n pi/2 around it (each square
  gives its corner a right angle, whichever diagonal splits it), so its defect is
  (4 - n) pi/2; corners no exposed square touches are not on the surface.
- V_hull is the hull of the full voxels' corners, computed exactly in integers
  (``hull_volume``).
"""

from __future__ import annotations

from typing import Any

import numba
import numpy as np

from softevo.evolution.genotype import Phenotype
from softevo.sim.system import largest_component

HALF_PI = np.pi / 2


# ---- symmetry ------------------------------------------------------------------------------------
@numba.njit(cache=True)
def _iou(inter: int, union: int) -> float:
    return inter / union if union > 0 else 1.0


@numba.njit(cache=True)
def _slice_shares(slices: np.ndarray) -> np.ndarray:
    """The six shares (r_v, r_h, r_pd, r_sd, t_v, t_h) averaged over the non-empty slices of
    a uint8 0/1 stack (n, rows, cols), shape (6,) (module doc)."""
    n, rows, cols = slices.shape
    side = max(rows, cols)
    half_r, half_c = (rows + 1) // 2, (cols + 1) // 2
    square = np.zeros((side, side), np.uint8)  # a slice padded to a square anchored at (0, 0)
    sums = np.zeros(6)
    used = 0
    for s in range(n):
        cut = slices[s]
        for r in range(rows):
            for c in range(cols):
                square[r, c] = cut[r, c]
        i0 = u0 = i1 = u1 = i2 = u2 = i3 = u3 = i4 = u4 = i5 = u5 = 0
        for r in range(rows):
            for c in range(cols):
                a = cut[r, c]
                b = cut[r, cols - 1 - c]
                i0 += a & b
                u0 += a | b
                b = cut[rows - 1 - r, c]
                i1 += a & b
                u1 += a | b
        if u0 == 0:  # an empty slice
            continue
        for r in range(side):
            for c in range(side):
                a = square[r, c]
                b = square[c, r]
                i2 += a & b
                u2 += a | b
                b = square[side - 1 - c, side - 1 - r]
                i3 += a & b
                u3 += a | b
        for r in range(half_r):
            for c in range(cols):
                a, b = cut[r, c], cut[rows - half_r + r, c]
                i4 += a & b
                u4 += a | b
        for r in range(rows):
            for c in range(half_c):
                a, b = cut[r, c], cut[r, cols - half_c + c]
                i5 += a & b
                u5 += a | b
        used += 1
        sums[0] += _iou(i0, u0)
        sums[1] += _iou(i1, u1)
        sums[2] += _iou(i2, u2)
        sums[3] += _iou(i3, u3)
        sums[4] += _iou(i4, u4)
        sums[5] += _iou(i5, u5)
    for k in range(6):
        sums[k] /= used
    return sums


def bounding_box(body: np.ndarray) -> np.ndarray:
    """``body`` cropped to the bounding box of its full voxels."""
    full = np.argwhere(np.asarray(body) > 0)
    low, high = full.min(axis=0), full.max(axis=0) + 1
    return np.asarray(body)[low[0] : high[0], low[1] : high[1], low[2] : high[2]]


@numba.njit(cache=True)
def _symmetry_axes(full: np.ndarray) -> np.ndarray:
    """``symmetry_axes`` of a uint8 0/1 body with at least one full voxel."""
    nx, ny, nz = full.shape
    lx, ly, lz, hx, hy, hz = nx, ny, nz, 0, 0, 0
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                if full[i, j, k]:
                    lx, ly, lz = min(lx, i), min(ly, j), min(lz, k)
                    hx, hy, hz = max(hx, i + 1), max(hy, j + 1), max(hz, k + 1)
    sx, sy, sz = hx - lx, hy - ly, hz - lz
    along_x = np.empty((sx, sy, sz), np.uint8)  # the box's slices along each axis
    along_y = np.empty((sy, sx, sz), np.uint8)
    along_z = np.empty((sz, sx, sy), np.uint8)
    for i in range(sx):
        for j in range(sy):
            for k in range(sz):
                cell = full[lx + i, ly + j, lz + k]
                along_x[i, j, k] = along_y[j, i, k] = along_z[k, i, j] = cell
    out = np.empty((3, 6))
    out[0] = _slice_shares(along_x)
    out[1] = _slice_shares(along_y)
    out[2] = _slice_shares(along_z)
    return out


def symmetry_axes(body: np.ndarray) -> np.ndarray:
    """Per-axis symmetry shares, shape (3, 6): rows x, y, z; columns r_v, r_h, r_pd, r_sd,
    t_v, t_h (module doc)."""
    return _symmetry_axes(_full(body).view(np.uint8))


def symmetry_index(body: np.ndarray) -> float:
    """Global symmetry index G_SI in [0, 1] (1 for a full box with equal sides)."""
    return float(symmetry_axes(body).mean())


# ---- the surface, counted on the lattice ------------------------------------------------------
_UNIT = np.eye(3, dtype=np.int64)


@numba.njit(cache=True)
def _exposed_squares_at_corners(full: np.ndarray) -> np.ndarray:
    """(nx+1, ny+1, nz+1) int64: at each lattice corner, how many exposed unit squares (faces
    of a full voxel towards an empty cell or the outside) have it as a corner."""
    nx, ny, nz = full.shape
    counts = np.zeros((nx + 1, ny + 1, nz + 1), np.int64)
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                if not full[i, j, k]:
                    continue
                for axis in range(3):
                    e, b, c = _UNIT[axis], _UNIT[(axis + 1) % 3], _UNIT[(axis + 2) % 3]
                    for side in range(2):
                        step = 2 * side - 1
                        ni, nj, nk = i + step * e[0], j + step * e[1], k + step * e[2]
                        if 0 <= ni < nx and 0 <= nj < ny and 0 <= nk < nz and full[ni, nj, nk]:
                            continue  # a face between two full voxels
                        ci, cj, ck = i + side * e[0], j + side * e[1], k + side * e[2]
                        for db in range(2):
                            for dc in range(2):
                                counts[ci + db * b[0] + dc * c[0], cj + db * b[1] + dc * c[1],
                                       ck + db * b[2] + dc * c[2]] += 1
    return counts


@numba.njit(cache=True)
def _on_line(axis, w, u, v):
    """(i, j, k) of position w along ``axis``, u and v along the two axes after it."""
    if axis == 0:
        return w, u, v
    if axis == 1:
        return v, w, u
    return u, v, w


@numba.njit(cache=True)
def _hull_candidates(full: np.ndarray) -> np.ndarray:
    """(m, 3) int64: the corners of the full voxels that can be vertices of their convex hull
    (a hull vertex lies on no segment between two other corners, so it is the first or the
    last corner of its lattice line along each of the three axes); every vertex of the hull
    is among them."""
    nx, ny, nz = full.shape
    corner = np.zeros((nx + 1, ny + 1, nz + 1), np.bool_)
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                if full[i, j, k]:
                    corner[i : i + 2, j : j + 2, k : k + 2] = True
    ends = np.zeros(corner.shape, np.int64)  # on how many axes a corner ends its line
    for axis in range(3):
        n, nu, nv = corner.shape[axis], corner.shape[(axis + 1) % 3], corner.shape[(axis + 2) % 3]
        for u in range(nu):
            for v in range(nv):
                first, last = -1, -1
                for w in range(n):
                    if corner[_on_line(axis, w, u, v)]:
                        last = w
                        if first < 0:
                            first = w
                if first >= 0:
                    ends[_on_line(axis, first, u, v)] += 1
                    if last != first:
                        ends[_on_line(axis, last, u, v)] += 1
    return np.argwhere(ends == 3)


@numba.njit(cache=True)
def _orient(points, a, b, c, d) -> int:
    """6 x the signed volume of tetrahedron (a, b, c, d): > 0 when d is on the side of
    triangle (a, b, c) its normal (b - a) x (c - a) points to. Exact on integer points."""
    ux, uy, uz = points[b, 0] - points[a, 0], points[b, 1] - points[a, 1], points[b, 2] - points[a, 2]
    vx, vy, vz = points[c, 0] - points[a, 0], points[c, 1] - points[a, 1], points[c, 2] - points[a, 2]
    wx, wy, wz = points[d, 0] - points[a, 0], points[d, 1] - points[a, 1], points[d, 2] - points[a, 2]
    return wx * (uy * vz - uz * vy) + wy * (uz * vx - ux * vz) + wz * (ux * vy - uy * vx)


@numba.njit(cache=True)
def _first_tetrahedron(points):
    """Four points spanning a tetrahedron (d = -1 if all are coplanar): the first point, the
    farthest from it, the farthest from their line, the farthest from their plane."""
    a, b, c, d = 0, 0, 0, -1
    best = 0
    for k in range(len(points)):
        dx, dy, dz = points[k, 0] - points[a, 0], points[k, 1] - points[a, 1], points[k, 2] - points[a, 2]
        if dx * dx + dy * dy + dz * dz > best:
            best, b = dx * dx + dy * dy + dz * dz, k
    ux, uy, uz = points[b, 0] - points[a, 0], points[b, 1] - points[a, 1], points[b, 2] - points[a, 2]
    best = 0
    for k in range(len(points)):
        vx, vy, vz = points[k, 0] - points[a, 0], points[k, 1] - points[a, 1], points[k, 2] - points[a, 2]
        cx, cy, cz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
        if cx * cx + cy * cy + cz * cz > best:
            best, c = cx * cx + cy * cy + cz * cz, k
    best = 0
    for k in range(len(points)):
        volume = abs(_orient(points, a, b, c, k))
        if volume > best:
            best, d = volume, k
    return a, b, c, d


@numba.njit(cache=True)
def _hull_volume6(points: np.ndarray) -> int:
    """6 x the volume of the convex hull of integer ``points`` (m, 3) int64, exactly
    (incremental hull with exact orientation tests; 0 if the points are coplanar)."""
    a, b, c, d = _first_tetrahedron(points)
    if d < 0:
        return 0
    if _orient(points, a, b, c, d) > 0:  # faces point outwards, away from d
        b, c = c, b
    capacity = 3 * len(points) + 8  # a hull of m points has at most 2m - 4 faces
    faces = np.empty((capacity, 3), np.int64)
    faces[0, 0], faces[0, 1], faces[0, 2] = a, b, c
    faces[1, 0], faces[1, 1], faces[1, 2] = a, d, b
    faces[2, 0], faces[2, 1], faces[2, 2] = b, d, c
    faces[3, 0], faces[3, 1], faces[3, 2] = c, d, a
    count = 4
    seen = np.empty(capacity, np.bool_)
    horizon = np.empty((3 * capacity, 2), np.int64)
    for p in range(len(points)):
        for f in range(count):
            seen[f] = _orient(points, faces[f, 0], faces[f, 1], faces[f, 2], p) > 0
        visible = 0
        for f in range(count):
            visible += seen[f]
        if visible == 0:
            continue  # inside or on the hull
        edges = 0
        for f in range(count):
            if not seen[f]:
                continue
            for e in range(3):
                u, v = faces[f, e], faces[f, (e + 1) % 3]
                shared = False  # its reverse edge belongs to another visible face
                for g in range(count):
                    if seen[g] and g != f:
                        for h in range(3):
                            if faces[g, h] == v and faces[g, (h + 1) % 3] == u:
                                shared = True
                if not shared:
                    horizon[edges, 0], horizon[edges, 1] = u, v
                    edges += 1
        kept = 0
        for f in range(count):
            if not seen[f]:
                faces[kept, 0], faces[kept, 1], faces[kept, 2] = faces[f, 0], faces[f, 1], faces[f, 2]
                kept += 1
        for e in range(edges):
            faces[kept, 0], faces[kept, 1], faces[kept, 2] = horizon[e, 0], horizon[e, 1], p
            kept += 1
        count = kept
    volume6 = 0
    for f in range(count):
        i, j, k = faces[f, 0], faces[f, 1], faces[f, 2]
        volume6 += (points[i, 0] * (points[j, 1] * points[k, 2] - points[j, 2] * points[k, 1])
                    + points[i, 1] * (points[j, 2] * points[k, 0] - points[j, 0] * points[k, 2])
                    + points[i, 2] * (points[j, 0] * points[k, 1] - points[j, 1] * points[k, 0]))
    return volume6


def hull_volume(points: np.ndarray) -> float:
    """Volume of the convex hull of integer ``points`` (m, 3), exact (0 if coplanar)."""
    return _hull_volume6(np.ascontiguousarray(points, dtype=np.int64)) / 6.0


def branching_index(body: np.ndarray) -> float:
    """BI = 1 - V / V_hull in [0, 1): V the number of full voxels (the surface mesh's
    volume), V_hull the volume of the hull of their corners (module doc)."""
    return _branching(_full(body))


def _full(body: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(body) > 0)


def _branching(full: np.ndarray) -> float:
    volume6 = _hull_volume6(_hull_candidates(full))
    return float(max(0.0, 1.0 - 6.0 * np.count_nonzero(full) / volume6))


def surface_vertices(body: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The surface mesh's vertices, (n_vertices, 3) int64 lattice corners in x-major order
    (voxel lengths), and how many exposed unit squares meet at each, (n_vertices,) int64."""
    counts = _exposed_squares_at_corners(np.ascontiguousarray(np.asarray(body) > 0))
    vertices = np.argwhere(counts)
    return vertices, counts[tuple(vertices.T)]


def surface_curvature(body: np.ndarray, radius: float = 0.0) -> np.ndarray:
    """Discrete Gaussian curvature measure (radians) at every vertex of the surface mesh,
    flat and straight-edge vertices included, shape (n_vertices,), vertices in x-major order:
    the sum of the angle defects (4 - squares) pi/2 of the vertices within ``radius`` (voxel
    lengths, inclusive) of each."""
    vertices, squares = surface_vertices(body)
    defect = (4 - squares) * HALF_PI
    if radius <= 0:
        return defect
    gaps = ((vertices[:, None, :] - vertices[None, :, :]) ** 2).sum(axis=2)
    return (gaps <= radius * radius) @ defect


def shape_entropy(body: np.ndarray, radius: float = 0.0) -> float:
    """Shannon entropy (bits) of the surface curvature binned by multiples of pi/2."""
    if radius <= 0:
        return _entropy(_full(body))
    multiples = np.round(surface_curvature(body, radius) / HALF_PI).astype(np.int64)
    return _entropy_of(np.bincount(multiples - multiples.min()) if multiples.size else multiples)


def _entropy(full: np.ndarray) -> float:
    """``shape_entropy`` at radius 0: a vertex where n squares meet has the multiple 4 - n."""
    squares = _exposed_squares_at_corners(full)
    return _entropy_of(np.bincount(squares.ravel())[:0:-1])  # n = max .. 1: multiples ascending


def _entropy_of(counts: np.ndarray) -> float:
    """Entropy (bits) of the bin counts, in order of their multiples of pi/2."""
    counts = counts[counts > 0]
    if counts.size == 0:
        return 0.0
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
    return describe_component(np.where(largest_component(body > 0), body, 0), frequency)


def describe_component(body: np.ndarray, frequency: float | None = None) -> dict[str, Any]:
    """``describe`` of a body that is one face-connected component already (a phenotype's),
    without labelling its components again."""
    body = np.asarray(body)
    full = _full(body)
    count = int(np.count_nonzero(full))
    result: dict[str, Any] = {
        "symmetry": float(_symmetry_axes(full.view(np.uint8)).mean()) if count else None,
        "branching": _branching(full) if count else None,
        "shape_entropy": _entropy(full) if count else None,
        "voxel_count": count,
        "active_share": float(np.count_nonzero(body == 2)) / count if count else 0.0,
    }
    if frequency is not None:
        result["frequency"] = float(frequency)
    return result


def describe_phenotype(phenotype: Phenotype) -> dict[str, Any]:
    """``describe`` of a phenotype's body (its largest component already: ``develop``),
    with its frequency."""
    return describe_component(phenotype.body, phenotype.frequency)
