"""The slow, obvious descriptors the fast ones are tested against (test_descriptors_reference.py):
the surface mesh built as triangles and measured by trimesh (its volume, its convex hull, its
vertex defects), and the symmetry shares sliced with NumPy. These are evolution/descriptors.py
as it was before the descriptors were counted on the lattice (issue 47)."""

import numpy as np
import trimesh

from softevo.evolution import descriptors
from softevo.sim.system import largest_component

# ---- the reference: the mesh, trimesh and NumPy slices ------------------------------------------
_UNIT_SQUARE = np.array([[0, 0], [1, 0], [1, 1], [0, 1]])


def _faces_for(full: np.ndarray, axis: int, sign: int) -> np.ndarray:
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
    return corners


def surface_mesh(body: np.ndarray) -> trimesh.Trimesh:
    """The voxel body's outer surface (faces between a full voxel and an empty cell or the
    outside, two triangles each, outward normals), vertices merged, in voxel lengths."""
    full = np.asarray(body) > 0
    quads = np.concatenate([_faces_for(full, a, s) for a in range(3) for s in (1, -1)])
    vertices, inverse = np.unique(quads.reshape(-1, 3), axis=0, return_inverse=True)
    corners = inverse.reshape(-1, 4)
    triangles = np.concatenate([corners[:, [0, 1, 2]], corners[:, [0, 2, 3]]])
    return trimesh.Trimesh(vertices.astype(float), triangles, process=False)


def reference_branching(body):
    mesh = surface_mesh(body)
    return float(max(0.0, 1.0 - mesh.volume / mesh.convex_hull.volume))


def reference_curvature(body, radius=0.0):
    mesh = surface_mesh(body)
    return trimesh.curvature.discrete_gaussian_curvature_measure(mesh, mesh.vertices, radius)


def reference_entropy(body, radius=0.0):
    curvature = reference_curvature(body, radius)
    if curvature.size == 0:
        return 0.0
    _, counts = np.unique(np.round(curvature / (np.pi / 2)).astype(int), return_counts=True)
    p = counts / counts.sum()
    return float(max(0.0, -(p * np.log2(p)).sum()))


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


def reference_symmetry_axes(body):
    box = descriptors.bounding_box(body) > 0
    per_axis = []
    for axis in range(3):
        slices = np.moveaxis(box, axis, 0)
        slices = slices[slices.any(axis=(1, 2))]
        per_axis.append(slice_symmetry(slices).mean(axis=0))
    return np.array(per_axis)


def reference_describe(body, frequency=None):
    body = np.asarray(body)
    kept = np.where(largest_component(body > 0), body, 0)
    count = int(np.count_nonzero(kept))
    measures = {
        "symmetry": lambda: float(reference_symmetry_axes(kept).mean()),
        "branching": lambda: reference_branching(kept),
        "shape_entropy": lambda: reference_entropy(kept),
    }
    result = {name: measure() if count else None for name, measure in measures.items()}
    result["voxel_count"] = count
    result["active_share"] = float(np.count_nonzero(kept == 2)) / count if count else 0.0
    return result if frequency is None else {**result, "frequency": float(frequency)}
