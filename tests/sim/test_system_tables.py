"""The lattice tables ``build_robot`` derives (``sim.system._lattice``, ``nearby``,
``surface_mesh``: numba kernels in ``sim.tables``) against the slow, obvious NumPy and loops
they replace (issue 47: the host side of an evaluation), element for element, on random
bodies and edge cases."""

import numpy as np
import pytest
from scipy import sparse

from softevo.sim.system import FACE_TRIANGLES, _lattice, largest_component, nearby, surface_mesh


def reference_nearby(nbr: np.ndarray, hops: int) -> np.ndarray:
    """Reachability by sparse matrix powers, each row ascending, padded with -1 at its end
    (one hop: the face neighbours, sorted the same way)."""
    if hops <= 1:
        rows = [sorted(u for u in row if u >= 0) for row in nbr.tolist()]
        return np.array([row + [-1] * (nbr.shape[1] - len(row)) for row in rows], dtype=np.int64)
    n = len(nbr)
    rows, cols = np.nonzero(nbr >= 0)
    adj = sparse.csr_matrix((np.ones(len(rows), np.int8), (rows, nbr[rows, cols])), shape=(n, n))
    reach = sparse.identity(n, dtype=np.int8, format="csr")
    step = reach + adj
    for _ in range(hops):
        reach = (reach @ step).astype(bool).astype(np.int8)
    reach = (reach - sparse.identity(n, dtype=np.int8, format="csr")).tocsr()
    reach.eliminate_zeros()
    counts = np.diff(reach.indptr)
    out = -np.ones((n, max(int(counts.max(initial=0)), 1)), dtype=np.int64)
    for v in range(n):
        row = reach.indices[reach.indptr[v]:reach.indptr[v + 1]]
        out[v, : len(row)] = np.sort(row)
    return out


def reference_surface_mesh(idx, lookup, nbr):
    """Vertices numbered as the triangles first meet them, voxel by voxel, face by face."""
    corners = np.array([[(c >> 2) & 1, (c >> 1) & 1, c & 1] for c in range(8)])
    faces, keys = [], {}
    for v, cell in enumerate(idx):
        for f in range(6):
            if nbr[v, f] >= 0:
                continue
            for tri in FACE_TRIANGLES[f]:
                ids = [keys.setdefault(tuple(cell + corners[c]), len(keys)) for c in tri]
                faces.append((*ids, v))
    vert = -np.ones((len(keys), 8), dtype=np.int64)
    shape = np.array(lookup.shape)
    for point, k in keys.items():
        slot = 0
        for c in range(8):
            cell = np.array(point) - corners[c]
            if np.all(cell >= 0) and np.all(cell < shape) and lookup[tuple(cell)] >= 0:
                vert[k, slot] = 8 * lookup[tuple(cell)] + c
                slot += 1
    return vert, np.array(faces, dtype=np.int64).reshape(-1, 4)


def bodies():
    rng = np.random.default_rng(5)
    out = [np.ones((1, 1, 1)), np.ones((7, 1, 1)), np.ones((7, 7, 7))]
    hollow = np.ones((5, 5, 5))
    hollow[2, 2, 2] = 0
    ring = np.ones((4, 4, 2))
    ring[1:3, 1:3] = 0
    out += [hollow, ring]
    for _ in range(40):
        shape = tuple(rng.integers(1, 8, size=3))
        body = (rng.random(shape) < rng.uniform(0.2, 0.9)).astype(np.int8)
        body.flat[0] = 1
        out.append(largest_component(body))
    return out


@pytest.mark.parametrize("hops", [1, 2, 3, 5])
def test_nearby_matches_sparse_matrix_powers(hops):
    for body in bodies():
        nbr = _lattice(np.asarray(body))[2]
        fast, slow = nearby(nbr, hops), reference_nearby(nbr, hops)
        assert fast.dtype == slow.dtype and fast.shape == slow.shape
        np.testing.assert_array_equal(fast, slow)


def test_surface_mesh_matches_the_loops():
    for body in bodies():
        idx, lookup, nbr = _lattice(np.asarray(body))[:3]
        for fast, slow in zip(surface_mesh(idx, lookup, nbr), reference_surface_mesh(idx, lookup, nbr),
                              strict=True):
            assert fast.dtype == slow.dtype and fast.shape == slow.shape
            np.testing.assert_array_equal(fast, slow)


def reference_lattice(body: np.ndarray):
    """The lattice tables by NumPy indexing (x-major voxels; links by axis, then voxel)."""
    idx = np.argwhere(body > 0)
    lookup = -np.ones(body.shape, dtype=np.int64)
    lookup[tuple(idx.T)] = np.arange(len(idx))
    padded = np.pad(lookup, 1, constant_values=-1)
    nbr = np.empty((len(idx), 6), dtype=np.int64)
    shifted = idx + 1
    for axis in range(3):
        for side, delta in enumerate((-1, 1)):
            off = shifted.copy()
            off[:, axis] += delta
            nbr[:, 2 * axis + side] = padded[tuple(off.T)]
    links = [
        (np.arange(len(idx))[nbr[:, 2 * a + 1] >= 0], nbr[nbr[:, 2 * a + 1] >= 0, 2 * a + 1], a)
        for a in range(3)
    ]
    link_neg = np.concatenate([n for n, _, _ in links]).astype(np.int64)
    link_pos = np.concatenate([p for _, p, _ in links]).astype(np.int64)
    link_axis = np.concatenate([np.full(len(n), a) for n, _, a in links]).astype(np.int64)
    vlink = np.full((len(idx), 6), len(link_neg), dtype=np.int64)
    vlink[link_neg, 2 * link_axis + 1] = np.arange(len(link_neg))
    vlink[link_pos, 2 * link_axis] = np.arange(len(link_neg))
    return idx, lookup, nbr, link_neg, link_pos, link_axis, vlink


def test_lattice_matches_numpy_indexing():
    rng = np.random.default_rng(7)
    cases = bodies() + [rng.choice([0, 1, 2], size=(6, 5, 4)).astype(np.int8) for _ in range(20)]
    for body in cases:
        for fast, slow in zip(_lattice(body), reference_lattice(np.asarray(body)), strict=True):
            assert fast.dtype == slow.dtype and fast.shape == slow.shape
            np.testing.assert_array_equal(fast, slow)


def test_initial_momenta_spin_the_body_as_np_cross_does():
    from softevo.sim.scene import parse_scene
    from softevo.sim.system import build_robot

    body = np.ones((3, 2, 4), int)
    body[1, 1, 2] = 0
    for omega in ([0.3, -1.7, 2.2], [0.0, 0.0, -0.0], [1e-3, 0.0, 5.0]):
        scene = parse_scene({"body": body.tolist(), "initial_velocity": [0.1, -0.2, 0.0],
                             "initial_angular_velocity": omega, "duration": {"seconds": 0.01}})
        robot = build_robot(scene)
        com = robot.pos.mean(axis=0)
        mass = robot.vconst[:, 0][:, None]
        expected = mass * (np.array([0.1, -0.2, 0.0]) + np.cross(np.array(omega), robot.pos - com))
        np.testing.assert_array_equal(robot.lin_mom, expected)
