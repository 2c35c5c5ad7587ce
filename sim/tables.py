"""The lattice tables of one robot (``sim.system.build_robot``), as numba kernels over
plain integer arrays. ``sim.system`` holds what each table means and imports these only
when it builds a robot, so that code which reads scenes or develops bodies without
simulating them (the coordinator, evolution) never loads numba. Each kernel gives the same
table, element for element, as the NumPy code it replaced (tests/sim/test_system_tables.py).
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def lattice_tables(full: np.ndarray):
    """``sim.system._lattice`` of a bool body (X, Y, Z)."""
    nx, ny, nz = full.shape
    lookup = np.full(full.shape, -1, np.int64)
    n = 0
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                if full[i, j, k]:
                    lookup[i, j, k] = n
                    n += 1
    idx = np.empty((n, 3), np.int64)
    nbr = np.full((n, 6), -1, np.int64)
    links_on_axis = np.zeros(3, np.int64)
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                v = lookup[i, j, k]
                if v < 0:
                    continue
                idx[v, 0], idx[v, 1], idx[v, 2] = i, j, k
                if i > 0:
                    nbr[v, 0] = lookup[i - 1, j, k]
                if i + 1 < nx:
                    nbr[v, 1] = lookup[i + 1, j, k]
                if j > 0:
                    nbr[v, 2] = lookup[i, j - 1, k]
                if j + 1 < ny:
                    nbr[v, 3] = lookup[i, j + 1, k]
                if k > 0:
                    nbr[v, 4] = lookup[i, j, k - 1]
                if k + 1 < nz:
                    nbr[v, 5] = lookup[i, j, k + 1]
                for axis in range(3):
                    links_on_axis[axis] += nbr[v, 2 * axis + 1] >= 0
    m = links_on_axis.sum()
    link_neg = np.empty(m, np.int64)
    link_pos = np.empty(m, np.int64)
    link_axis = np.empty(m, np.int64)
    vlink = np.full((n, 6), m, np.int64)
    link = 0
    for axis in range(3):
        for v in range(n):
            other = nbr[v, 2 * axis + 1]
            if other >= 0:
                link_neg[link], link_pos[link], link_axis[link] = v, other, axis
                vlink[v, 2 * axis + 1] = vlink[other, 2 * axis] = link
                link += 1
    return idx, lookup, nbr, link_neg, link_pos, link_axis, vlink


@numba.njit(cache=True)
def within_hops(nbr: np.ndarray, hops: int) -> np.ndarray:
    """``sim.system.nearby`` for hops >= 2: each voxel's reach as a bit set of the voxels, grown one bond
    at a time by the union of its neighbours' reach, read back in ascending order."""
    n = len(nbr)
    words = (n + 63) // 64
    one = np.uint64(1)
    reach = np.zeros((n, words), np.uint64)
    for v in range(n):
        reach[v, v // 64] |= one << np.uint64(v % 64)
    grown = reach.copy()
    for _ in range(hops):
        for v in range(n):
            for f in range(nbr.shape[1]):
                u = nbr[v, f]
                if u >= 0:
                    for w in range(words):
                        grown[v, w] |= reach[u, w]
        reach[:] = grown
    width = 1
    for v in range(n):
        reach[v, v // 64] &= ~(one << np.uint64(v % 64))  # itself left out
        count = 0
        for w in range(words):
            bits = reach[v, w]
            while bits:
                bits &= bits - one
                count += 1
        width = max(width, count)
    out = np.full((n, width), -1, np.int64)
    for v in range(n):
        k = 0
        for w in range(words):
            bits = reach[v, w]
            for b in range(64):
                if bits == 0:
                    break
                if bits & one:
                    out[v, k] = 64 * w + b
                    k += 1
                bits >>= one
    return out


@numba.njit(cache=True)
def surface_mesh_tables(idx, lookup, nbr, face_triangles, corners):
    """``sim.system.surface_mesh``: (mesh_vert, mesh_face); ``face_triangles`` (6, 2, 3) the
    corner codes of each face's triangles, ``corners`` (8, 3) each code's offsets."""
    nx, ny, nz = lookup.shape
    number = np.full((nx + 1, ny + 1, nz + 1), -1, np.int64)  # each lattice corner's vertex
    points = np.empty(((nx + 1) * (ny + 1) * (nz + 1), 3), np.int64)
    faces = np.empty((12 * len(idx), 4), np.int64)
    nv = nf = 0
    for v in range(len(idx)):
        for f in range(6):
            if nbr[v, f] >= 0:
                continue
            for t in range(2):
                for slot in range(3):
                    code = face_triangles[f, t, slot]
                    x, y, z = (idx[v, 0] + corners[code, 0], idx[v, 1] + corners[code, 1],
                               idx[v, 2] + corners[code, 2])
                    if number[x, y, z] < 0:
                        number[x, y, z] = nv
                        points[nv, 0], points[nv, 1], points[nv, 2] = x, y, z
                        nv += 1
                    faces[nf, slot] = number[x, y, z]
                faces[nf, 3] = v
                nf += 1
    vert = np.full((nv, 8), -1, np.int64)
    for k in range(nv):
        slot = 0
        for c in range(8):  # the cell that has this vertex as its corner c
            x, y, z = points[k, 0] - corners[c, 0], points[k, 1] - corners[c, 1], points[k, 2] - corners[c, 2]
            if 0 <= x < nx and 0 <= y < ny and 0 <= z < nz and lookup[x, y, z] >= 0:
                vert[k, slot] = 8 * lookup[x, y, z] + c
                slot += 1
    return vert, faces[:nf].copy()
