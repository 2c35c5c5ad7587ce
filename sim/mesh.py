"""The deformed surface mesh of a voxel robot, as VoxCAD draws it, from recorded motion.

The topology is the paper's engine's (``sim.system.surface_mesh``, the one the water drag
uses): a vertex per lattice corner on the surface, two triangles per exposed face. A vertex's
position is the mean, over the voxels whose cells share that corner, of each voxel's own
corner (``mesh_vertices``; ``kernels.mesh_vertices_kernel`` computes the same mean inside the
step). A voxel's corner is its centre plus its axes times (+-1/2): in the simulator the axes
are the voxel's rotation times its size; a recording holds only the centres, so
``voxel_axes`` estimates each voxel's axes from its neighbours' centres. In the rest lattice
every estimate is exact and every shared corner is one point: no gaps.

Arrays: ``voxels`` (n, 3) int lattice indices; ``positions`` (n, 3) metres; ``axes``
(n, 3, 3) metres, ``axes[v, a]`` voxel v's edge vector along lattice axis a; ``corners``
(n, 8, 3) metres, corner code 4 dx + 2 dy + dz; ``mesh_vert`` (nv, 8) int, 8 voxel + corner
of each voxel sharing the vertex (-1 pads); ``mesh_face`` (nf, 4) int, a triangle's three
vertices (counter-clockwise seen from outside) and the voxel whose face it covers.
"""

from __future__ import annotations

import numpy as np

from .system import _lattice, surface_mesh

# (8, 3) offset of each corner code from the centre, in edges: 4 dx + 2 dy + dz, d in {0, 1}
CORNER_SIGNS = np.array([[(c >> 2) & 1, (c >> 1) & 1, c & 1] for c in range(8)], float) - 0.5


def lattice_mesh(voxels: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(nbr, mesh_vert, mesh_face) of the voxels at lattice indices ``voxels`` (n, 3), in
    the order given; ``nbr`` (n, 6) the neighbour on -x, +x, -y, +y, -z, +z (-1: none)."""
    voxels = np.asarray(voxels, dtype=np.int64).reshape(-1, 3)
    if len(voxels) == 0:
        return np.zeros((0, 6), np.int64), np.zeros((0, 8), np.int64), np.zeros((0, 4), np.int64)
    cells = voxels - voxels.min(axis=0)
    body = np.zeros(cells.max(axis=0) + 1, dtype=np.int8)
    body[tuple(cells.T)] = 1
    idx, lookup, nbr = _lattice(body)[:3]
    given = np.empty(len(idx), dtype=np.int64)  # given[r]: the given index of lattice voxel r
    given[lookup[tuple(cells.T)]] = np.arange(len(cells))
    mesh_vert, mesh_face = surface_mesh(idx, lookup, nbr)
    mesh_vert = np.where(mesh_vert >= 0, 8 * given[mesh_vert >> 3] + (mesh_vert & 7), -1)
    mesh_face = np.column_stack([mesh_face[:, :3], given[mesh_face[:, 3]]])
    order = np.argsort(given)
    nbr = np.where(nbr >= 0, given[nbr], -1)[order]
    return nbr, mesh_vert, mesh_face


def voxel_axes(positions: np.ndarray, nbr: np.ndarray, voxel_size: float) -> np.ndarray:
    """Each voxel's edge vectors (n, 3, 3) from its neighbours' centres: along an axis with
    neighbours on both sides, half the vector between them; on one side, the vector to it.
    An axis without neighbours is perpendicular to the others, ``voxel_size`` long, right-
    handed (one axis alone is completed from the rest axis least aligned with it); a voxel
    alone keeps the rest axes."""
    positions = np.asarray(positions, dtype=float)
    n = len(positions)
    padded = np.vstack([positions, np.zeros((1, 3))])  # row -1: a missing neighbour
    low, high = padded[nbr[:, 0::2]], padded[nbr[:, 1::2]]  # (n, 3 axes, 3)
    has_low, has_high = (nbr[:, 0::2] >= 0)[..., None], (nbr[:, 1::2] >= 0)[..., None]
    centre = positions[:, None, :]
    axes = np.where(
        has_low & has_high,
        (high - low) / 2,
        np.where(has_high, high - centre, np.where(has_low, centre - low, 0.0)),
    )
    known = (has_low | has_high)[..., 0]  # (n, 3)
    count = known.sum(axis=1)
    for a in range(3):
        b, c = (a + 1) % 3, (a + 2) % 3
        two = (count == 2) & ~known[:, a]  # a missing: b x c
        axes[two, a] = voxel_size * _unit(np.cross(axes[two, b], axes[two, c]))
        one = (count == 1) & known[:, a]  # only a known: b, c from the rest axes
        u = _unit(axes[one, a])
        along_b = np.abs(u[:, b : b + 1]) <= np.sqrt(0.75)  # e_b not near a: b from it
        rest_b = np.eye(3)[b] - u[:, b : b + 1] * u
        rest_c = np.eye(3)[c] - u[:, c : c + 1] * u
        axis_b = np.where(along_b, _unit(rest_b), _unit(np.cross(_unit(rest_c), u)))
        axes[one, b] = voxel_size * axis_b
        axes[one, c] = voxel_size * _unit(np.cross(u, axis_b))
    axes[count == 0] = voxel_size * np.eye(3)
    return axes.reshape(n, 3, 3)


def _unit(vectors: np.ndarray) -> np.ndarray:
    return vectors / np.maximum(np.linalg.norm(vectors, axis=-1, keepdims=True), 1e-300)


def voxel_corners(positions: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """Each voxel's 8 corners (n, 8, 3), metres: its centre plus its axes times
    ``CORNER_SIGNS``."""
    return np.asarray(positions, float)[:, None, :] + np.einsum("cj,njx->ncx", CORNER_SIGNS, axes)


def mesh_vertices(mesh_vert: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """Vertex positions (nv, 3), metres: for each vertex, the mean of the corners
    (``corners`` (n, 8, 3)) of the voxels that share it."""
    flat = corners.reshape(-1, 3)
    present = mesh_vert >= 0
    total = np.einsum("vs,vsx->vx", present, flat[np.where(present, mesh_vert, 0)])
    return total / np.maximum(present.sum(axis=1), 1)[:, None]


def deformed_mesh(
    positions: np.ndarray, nbr: np.ndarray, mesh_vert: np.ndarray, voxel_size: float
) -> np.ndarray:
    """Vertex positions (nv, 3), metres, of the surface mesh of one recorded frame
    (``positions`` (n, 3) voxel centres)."""
    axes = voxel_axes(positions, nbr, voxel_size)
    return mesh_vertices(mesh_vert, voxel_corners(positions, axes))
