"""The pieces of the step that read arrays, written once for both engines.

``sim.physics`` holds the formulas as functions of scalars; the few per-element bodies of
the step that must index a robot's arrays are here: whether a pair of voxels is in
``near``'s list (``listed``), whether it is a contact candidate (``is_candidate``), and one
candidate pair's contact force (``pair_force``). Their arrays are flat (a voxel's x, y, z
at 3 v, its constants at ``stride`` v), as both engines can hand them over. ``compiled(jit,
phys)`` binds them to a target's physics (``sim.physics.compiled``):

- ``sim.kernels``: ``compiled(njit(inline="always", ...), physics)``, inlined into its loops;
- ``sim.cuda_kernels``: ``compiled(cuda.jit(device=True), physics)``, device functions (on
  numba-cuda's simulator the plain functions).

The loops around them stay each engine's own: a pass over sorted candidates, or over the
pairs, on the CPU; a thread per voxel on the GPU.
"""

from __future__ import annotations

from types import SimpleNamespace

from . import physics
from .physics import contact_overlap, contact_push  # the plain ones; ``compiled`` binds a target's
from .system import V_CCOLL, V_INV_MASS, V_KFLOOR

PIECES = ("listed", "is_candidate", "pair_force")


def listed(near, width, i, j):
    """Whether row i of ``near`` (flat, ``width`` entries per row, ascending, -1 pads at the
    end: ``system.nearby``) holds j: a binary search for the first entry not below j (a pad
    counts as above every voxel)."""
    lo, hi = 0, width
    while lo < hi:
        mid = (lo + hi) >> 1
        w = near[i * width + mid]
        below = w >= 0 and w < j
        lo = mid + 1 if below else lo
        hi = hi if below else mid
    return lo < width and near[i * width + lo] == j


def is_candidate(near, width, i, j, dx, dy, dz, reach2):
    """Whether voxels i and j (d = x_j - x_i) are contact candidates: nearer than the
    candidate radius (squared: reach2; ``physics.candidate_radius``) and not in ``near``'s
    list for each other (bonded, or within the model's collision horizon)."""
    return dx * dx + dy * dy + dz * dz < reach2 and not listed(near, width, i, j)


def pair_force(pos, lin_mom, size, vconst, stride, i, j, reach, stiff, damp, vs, cs):
    """The contact force on voxel j from voxel i of a candidate pair (i gets its opposite):
    whether they touch (``physics.contact_overlap``), and the force (``physics.contact_push``;
    zero when they do not). ``vconst``: the voxels' constants, ``stride`` per voxel
    (``sim.system``'s V_*); ``reach``, ``stiff``, ``damp``: the model's contact parameters;
    voxel v's component c of ``pos`` and ``lin_mom`` is at ``vs * v + cs * c`` (3, 1 for
    (x, y, z) per voxel, 1, n for rows by component)."""
    a, b = vs * i, vs * j  # offsets of i's and j's x
    dx = pos[b] - pos[a]
    dy = pos[b + cs] - pos[a + cs]
    dz = pos[b + 2 * cs] - pos[a + 2 * cs]
    overlap, dist = contact_overlap(dx, dy, dz, size[i], size[j], reach)
    if overlap <= 0.0 or dist == 0.0:
        return False, 0.0, 0.0, 0.0
    ci, cj = stride * i, stride * j
    inv_mi, inv_mj = vconst[ci + V_INV_MASS], vconst[cj + V_INV_MASS]
    fx, fy, fz = contact_push(
        overlap, dist, dx, dy, dz, lin_mom[b] * inv_mj - lin_mom[a] * inv_mi,
        lin_mom[b + cs] * inv_mj - lin_mom[a + cs] * inv_mi,
        lin_mom[b + 2 * cs] * inv_mj - lin_mom[a + 2 * cs] * inv_mi,
        vconst[ci + V_KFLOOR], vconst[cj + V_KFLOOR], vconst[ci + V_CCOLL], vconst[cj + V_CCOLL],
        stiff, damp)
    return True, fx, fy, fz


def compiled(jit, phys) -> SimpleNamespace:
    """The functions of ``PIECES`` compiled by ``jit``, calling the target's physics
    ``phys`` (``physics.compiled``) and one another (``physics.bind``)."""
    space = {**globals(), **vars(phys)}
    return physics.bind(jit, [globals()[name] for name in PIECES], space)

