"""sim.mesh: the surface mesh drawn from recorded centres. Undeformed, its vertices are the
lattice corners, one vertex per shared corner (no gaps); deformed, it stays closed (every
edge in exactly two triangles, each way once); a rigid motion moves it rigidly; the fast
functions agree with slow loops, and the vertex mean with the drag kernel's."""

from __future__ import annotations

import numpy as np
import pytest

from softevo.sim import kernels
from softevo.sim.mesh import (
    CORNER_SIGNS,
    deformed_mesh,
    lattice_mesh,
    mesh_vertices,
    voxel_axes,
    voxel_corners,
)
from softevo.sim.system import exposed_faces

L = 0.01


def random_voxels(rng: np.random.Generator, shape=(4, 4, 3), fill=0.6) -> np.ndarray:
    """Lattice indices of a random body, shuffled (the functions keep any order)."""
    voxels = np.argwhere(rng.random(shape) < fill)
    return voxels[rng.permutation(len(voxels))]


def l_shape() -> np.ndarray:
    """A body without edge-only contacts: an L of 2 x 3 x 2 with a tower."""
    block = [(i, j, k) for i in range(2) for j in range(3) for k in range(2)]
    return np.array([*block, (2, 0, 0), (3, 0, 0), (0, 0, 2), (0, 0, 3)])


def rotation(rng: np.random.Generator) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def edges_of(mesh_face: np.ndarray) -> np.ndarray:
    """(3 nf, 2) directed edges of the triangles."""
    tri = mesh_face[:, :3]
    return np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])


def signed_volume(vertices: np.ndarray, mesh_face: np.ndarray) -> float:
    a, b, c = (vertices[mesh_face[:, k]] for k in range(3))
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6)


@pytest.mark.parametrize("seed", range(5))
def test_undeformed_vertices_are_the_lattice_corners_one_per_corner(seed):
    voxels = random_voxels(np.random.default_rng(seed))
    nbr, mesh_vert, mesh_face = lattice_mesh(voxels)
    vertices = deformed_mesh((voxels + 0.5) * L, nbr, mesh_vert, L)
    lattice = vertices / L
    assert np.allclose(lattice, np.round(lattice), atol=1e-9)
    points = {tuple(p) for p in np.round(lattice).astype(int)}
    assert len(points) == len(vertices)  # one vertex per shared corner: no gaps
    exposed = (nbr < 0).sum()
    assert len(mesh_face) == 2 * exposed
    assert signed_volume(vertices, mesh_face) == pytest.approx(len(voxels) * L**3)


def test_every_corner_of_an_exposed_face_is_a_vertex():
    voxels = l_shape()
    nbr, mesh_vert, mesh_face = lattice_mesh(voxels)
    used = np.unique(mesh_face[:, :3])
    assert used.tolist() == list(range(len(mesh_vert)))
    sharing = (mesh_vert >= 0).sum(axis=1)
    assert sharing.min() >= 1 and sharing.max() <= 8


@pytest.mark.parametrize("seed", range(5))
def test_a_deformed_robot_is_watertight(seed):
    rng = np.random.default_rng(seed)
    voxels = l_shape()
    nbr, mesh_vert, mesh_face = lattice_mesh(voxels)
    centres = (voxels + 0.5) * L @ rotation(rng).T + rng.normal(0, 0.15 * L, (len(voxels), 3))
    vertices = deformed_mesh(centres, nbr, mesh_vert, L)
    directed = edges_of(mesh_face)
    undirected, count = np.unique(np.sort(directed, axis=1), axis=0, return_counts=True)
    assert np.all(count == 2), "an edge not shared by exactly two triangles"
    forward = {tuple(e) for e in directed}
    assert len(forward) == len(directed) and all((b, a) in forward for a, b in directed)
    a, b, c = (vertices[mesh_face[:, k]] for k in range(3))
    assert np.linalg.norm(np.cross(b - a, c - a), axis=1).min() > 0
    assert 0.5 < signed_volume(vertices, mesh_face) / (len(voxels) * L**3) < 1.5


@pytest.mark.parametrize("seed", range(5))
def test_any_body_pairs_each_directed_edge_with_its_reverse(seed):
    """Bodies with edge-only contacts have edges in four triangles; still closed."""
    voxels = random_voxels(np.random.default_rng(seed))
    _, _, mesh_face = lattice_mesh(voxels)
    directed = [tuple(e) for e in edges_of(mesh_face)]
    assert sorted(directed) == sorted((b, a) for a, b in directed)


@pytest.mark.parametrize("shape", [(2, 2, 2), (3, 2, 4), (5, 3, 2)])
def test_a_rigid_motion_moves_the_mesh_rigidly(shape):
    """Where every voxel has neighbours along two axes or more (an axis alone is completed
    from the rest axes, which a rotation does not move)."""
    rng = np.random.default_rng(sum(shape))
    voxels = np.argwhere(np.ones(shape))
    nbr, mesh_vert, _ = lattice_mesh(voxels)
    turn, shift = rotation(rng), rng.normal(size=3)
    rest = deformed_mesh((voxels + 0.5) * L, nbr, mesh_vert, L)
    moved = deformed_mesh((voxels + 0.5) * L @ turn.T + shift, nbr, mesh_vert, L)
    assert moved == pytest.approx(rest @ turn.T + shift, abs=1e-12)


def slow_axes(positions, nbr, size):
    """voxel_axes one voxel and one axis at a time."""
    out = np.zeros((len(positions), 3, 3))
    for v in range(len(positions)):
        known = []
        for a in range(3):
            low, high = nbr[v, 2 * a], nbr[v, 2 * a + 1]
            if low >= 0 and high >= 0:
                out[v, a] = (positions[high] - positions[low]) / 2
            elif high >= 0:
                out[v, a] = positions[high] - positions[v]
            elif low >= 0:
                out[v, a] = positions[v] - positions[low]
            else:
                continue
            known.append(a)
        if len(known) == 0:
            out[v] = size * np.eye(3)
        elif len(known) == 1:
            a = known[0]
            b, c = (a + 1) % 3, (a + 2) % 3
            u = out[v, a] / np.linalg.norm(out[v, a])
            if abs(u[b]) <= np.sqrt(0.75):
                w = np.eye(3)[b] - u[b] * u
                out[v, b] = size * w / np.linalg.norm(w)
            else:
                w = np.eye(3)[c] - u[c] * u
                w = np.cross(w / np.linalg.norm(w), u)
                out[v, b] = size * w / np.linalg.norm(w)
            w = np.cross(u, out[v, b])
            out[v, c] = size * w / np.linalg.norm(w)
        elif len(known) == 2:
            (a,) = set(range(3)) - set(known)
            w = np.cross(out[v, (a + 1) % 3], out[v, (a + 2) % 3])
            out[v, a] = size * w / np.linalg.norm(w)
    return out


def slow_vertices(mesh_vert, positions, axes):
    out = np.zeros((len(mesh_vert), 3))
    for k, row in enumerate(mesh_vert):
        points = [
            positions[code // 8] + CORNER_SIGNS[code % 8] @ axes[code // 8] for code in row if code >= 0
        ]
        out[k] = np.mean(points, axis=0)
    return out


@pytest.mark.parametrize("seed", range(6))
def test_fast_mesh_agrees_with_slow_loops(seed):
    rng = np.random.default_rng(seed)
    shape = [(4, 4, 3), (5, 1, 1), (1, 4, 1), (3, 3, 1), (1, 1, 1), (4, 2, 2)][seed]
    voxels = random_voxels(rng, shape, fill=0.7 if seed != 4 else 1.0)
    if len(voxels) == 0:
        voxels = np.zeros((1, 3), int)
    nbr, mesh_vert, _ = lattice_mesh(voxels)
    turn = rotation(rng) if seed % 2 else np.eye(3)[[1, 0, 2]] @ np.diag([1, -1, 1])
    centres = (voxels + 0.5) * L @ turn.T + rng.normal(0, 0.1 * L, (len(voxels), 3))
    axes = voxel_axes(centres, nbr, L)
    assert axes == pytest.approx(slow_axes(centres, nbr, L), abs=1e-12)
    fast = mesh_vertices(mesh_vert, voxel_corners(centres, axes))
    assert fast == pytest.approx(slow_vertices(mesh_vert, centres, axes), abs=1e-12)


def test_vertex_mean_is_the_drag_kernels():
    """The kernels' vertices (corners from quaternions and sizes, in the step:
    ``kernels.mesh_vertices_kernel``) are ``mesh_vertices`` of those corners: one definition
    of the mesh."""
    rng = np.random.default_rng(7)
    voxels = l_shape()
    nbr, mesh_vert, mesh_face = lattice_mesh(voxels)
    n = len(voxels)
    pos = (voxels + 0.5) * L + rng.normal(0, 0.05 * L, (n, 3))
    quat = rng.normal(size=(n, 4)) * [1, 0.1, 0.1, 0.1]
    quat /= np.linalg.norm(quat, axis=1, keepdims=True)
    size = L * (1 + rng.uniform(-0.2, 0.2, n))
    vert_pos, corner_scratch = np.zeros((len(mesh_vert), 3)), np.zeros((3, 8, n))
    kernels.mesh_vertices_kernel(mesh_vert, exposed_faces(nbr), L, np.ascontiguousarray(pos.T),
                                 np.ascontiguousarray(quat.T), size, vert_pos, corner_scratch)
    corners = np.zeros((n, 8, 3))
    for v in range(n):
        turn = np.array(kernels.rotation_matrix(*quat[v])).reshape(3, 3)
        for c, signs in enumerate(CORNER_SIGNS):
            extent = [size[v] if nbr[v, 2 * a + (signs[a] > 0)] >= 0 else L for a in range(3)]
            corners[v, c] = pos[v] + turn @ (signs * extent)
    assert mesh_vertices(mesh_vert, corners) == pytest.approx(vert_pos, abs=1e-12)
    assert corner_scratch.transpose(2, 1, 0) == pytest.approx(corners, abs=1e-12)


@pytest.mark.parametrize("seed", range(4))
def test_mesh_drag_kernel_is_the_sum_over_triangles(seed):
    """The CPU's drag reads an exposed face's two triangles at once (consecutive rows that
    share their voxel and first vertex): the forces it adds are, triangle by triangle, the
    drag law -drag A (v.n)^2 n on the triangles moving into the fluid (a slow loop)."""
    rng = np.random.default_rng(seed)
    voxels = random_voxels(rng, (4, 3, 3), fill=0.7) if seed else l_shape()
    _, _, mesh_face = lattice_mesh(voxels)
    assert len(mesh_face) % 2 == 0
    assert (mesh_face[0::2, 0] == mesh_face[1::2, 0]).all()
    assert (mesh_face[0::2, 3] == mesh_face[1::2, 3]).all()
    n, nv = len(voxels), int(mesh_face[:, :3].max()) + 1
    vert_pos = rng.normal(0, L, (nv, 3))
    lin_mom = rng.normal(0, 1e-3, (n, 3))
    inv_mass = rng.uniform(500, 2000, n)
    drag = 750.0
    force = rng.normal(0, 1e-3, (n, 3))
    expected = force.copy()
    into = 0
    for a, b, c, v in mesh_face:
        normal2a = np.cross(vert_pos[b] - vert_pos[a], vert_pos[c] - vert_pos[a])  # 2 A n
        area = 0.5 * np.linalg.norm(normal2a)
        unit = normal2a / np.linalg.norm(normal2a)
        speed = lin_mom[v] @ unit * inv_mass[v]
        if speed > 0:
            expected[v] -= drag * area * speed**2 * unit
            into += 1
    assert 0 < into < len(mesh_face)
    rows = np.ascontiguousarray(force.T)  # the kernels' rows by component
    kernels.mesh_drag_kernel(drag, mesh_face, np.ascontiguousarray(lin_mom.T), inv_mass, vert_pos,
                             rows)
    assert rows.T == pytest.approx(expected, rel=1e-12, abs=1e-15)
