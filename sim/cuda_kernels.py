"""GPU kernels (numba-cuda): one thread block per robot, many steps per launch.

``rollout_kernel(shared, threads)`` builds the kernel that steps the robots of a batch for up
to ``chunk`` steps, block r for robot ``which[r]``. A block's threads share the robot's
voxels and links (thread t takes voxels t, t + T, ... and links likewise) and meet at block
syncs between the sub-steps of a step, which carry the names of ``sim.kernels``' sub-steps:

    sample | actuate | link_forces, mesh_vertices, contact_list (when stale)
    | gather (per voxel: link_sums, contact_forces, mesh_drag) | voxel_update | reductions

Everything per element is the code the CPU engine runs: ``sim.physics`` (a voxel's actuated
size, a link's frame, its hysteresis transition, damping and loads, a voxel's sum of its
links' loads, the rebuild trigger, a facet's normal and drag, a mesh corner, a voxel's
update, the sampling, the order of the failure checks) and ``sim.substeps`` (the candidate
test, a pair's contact force), compiled here as device functions. What is the GPU's own is
how the work is spread over a block: the loops over a thread's elements; a link's frame
change computed in the same pass (the CPU marks it for a second one); each surface voxel's
candidates found by one thread's search over the surface (the CPU scans its far pairs); a
vertex's corners computed where it is averaged (the CPU keeps every voxel's corners); each
voxel gathering its own link loads, contacts and facet drag, where the CPU scatters them;
the reductions over the block.

- ``shared=True``: the robot's body state, sizes, forces and link state live in the block's
  dynamic shared memory for the launch (copied in at its start, out at its end);
  ``shared=False`` runs the same steps on the global arrays (robots too large to fit).
- A robot that has run its steps or diverged is finished: its block returns at once in
  every later launch, and inside a launch its block leaves the step loop.
- Reductions are fixed-order trees in shared memory, and each voxel gathers its own forces
  (no atomics on floats), so a run is the same on every launch.

Indices inside a robot are local (``sim.system.pack``); arrays are flat, robot r's slice of
each starting at its offset. On numba-cuda's simulator (``NUMBA_ENABLE_CUDASIM=1``) the
same source runs as Python, the physics as the plain functions of ``sim.physics``.
"""

from __future__ import annotations

import math
from functools import cache
from typing import Any, NamedTuple

import numpy as np
from numba import cuda, float64
from numba.cuda import config as cuda_config

from . import physics, substeps
from .system import (
    COM_SAMPLES,
    FLAG_ACTIVE,
    FLAG_FIXED,
    MAX_CONTACTS,
    N_FPARAMS,
    N_IPARAMS,
    N_VCONST,
    STATUS_OK,
    V_CCOLL,
    V_CGANG,
    V_CGLIN,
    V_INV_INERTIA,
    V_INV_MASS,
    V_KFLOOR,
    V_MASS,
    V_OMEGA,
    V_WEIGHT,
    params_of,
)

SIMULATOR = bool(cuda_config.ENABLE_CUDASIM)
COM_ROWS = COM_SAMPLES + 3  # rows of a robot's centre-of-mass trajectory
VOXEL_WORDS = 20  # float64 per voxel in shared memory: pos 3, quat 4, momenta 6, size 1, force 3, moment 3
LINK_WORDS = 18  # per link: state 9 (previous deformation 8, frame mode), loads 9
LINK_STATE, LINK_LOADS = 9, 9
SCRATCH_WORDS = 3  # float64 in a block's dynamic shared memory beyond one per thread: the flags
# control words of a robot, ``ctl[r, :]``
C_RUNNING, C_STEP, C_CODE, C_DONE, C_NCOM = range(5)
N_CTL = 5


def _fma_device(a, b, c):
    return cuda.fma(a, b, c)


if SIMULATOR:  # the plain functions: the simulator runs kernels as Python
    def device(f):
        return f

    substep = device
    phys = physics.compiled(device, physics.fma)
    phys32 = physics.compiled(device, physics.fma, real=np.float32)
else:
    device = cuda.jit(device=True)
    substep = cuda.jit(device=True, forceinline=True)  # the step's sub-steps, inlined by NVVM
    _fma = device(_fma_device)
    phys = physics.compiled(device, _fma)
    phys32 = physics.compiled(device, _fma, real=np.float32)

rotation_matrix, actuation, voxel_size = phys.rotation_matrix, phys.actuation, phys.voxel_size
rest_length, voxel_loads, candidate_radius = phys.rest_length, phys.voxel_loads, phys.candidate_radius
contacts_stale, travel_after, widen = phys.contacts_stale, phys.travel_after, phys.widen
nan_min, nan_max, displacement_spread = phys.nan_min, phys.nan_max, phys.displacement_spread
facet_force, voxel_corner = phys.facet_force, phys.voxel_corner
voxel_update_of, voxel_world, centre_of_mass = phys.voxel_update, phys.voxel_world, phys.centre_of_mass
voxel_turn = phys.voxel_turn
frame_due, com_due, step_status = phys.frame_due, phys.com_due, phys.step_status
# the array-reading pieces both engines share (``sim.substeps``)
sub = substeps.compiled(device, phys)
is_candidate, pair_force = sub.is_candidate, sub.pair_force
params = device(params_of)


@device
def face_loads(loads, j):
    """The nine loads of link j (``physics.voxel_loads``); zeros for no link (j < 0)."""
    if j < 0:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    o = j * LINK_LOADS
    return (loads[o], loads[o + 1], loads[o + 2], loads[o + 3], loads[o + 4], loads[o + 5],
            loads[o + 6], loads[o + 7], loads[o + 8])


@device
def com_sample(n, vc, pos, com, row):
    """The mass-weighted centre of mass into ``com[row, 1:4]`` (one thread;
    ``physics.centre_of_mass``)."""
    com[row * 4 + 1], com[row * 4 + 2], com[row * 4 + 3] = centre_of_mass(
        n, vc, N_VCONST, V_WEIGHT, pos, 3, 1)


@device
def tree(red, t, nt, lowest):
    """red[0] = the smallest (``lowest``) or the largest of red[:nt] (``physics.nan_min``,
    ``nan_max``, as ``kernels.surface_moved`` folds them), by a fixed-order tree; every
    thread of the block calls it."""
    span = 1
    while span < nt:
        span *= 2
    span //= 2
    while span > 0:
        if t < span and t + span < nt:
            a, b = red[t], red[t + span]
            red[t] = nan_min(a, b) if lowest else nan_max(a, b)
        cuda.syncthreads()
        span //= 2


class Robots(NamedTuple):
    """Per-robot rows and the offsets of each robot's slices (``sim.system.pack``)."""

    fp: Any  # (R * N_FPARAMS,) float parameters (``F_*``)
    ip: Any  # (R * N_IPARAMS,) integer parameters (``I_*``)
    voff: Any  # (R + 1,) first voxel of each robot
    loff: Any  # (R + 1,) first link
    soff: Any  # (R + 1,) first surface voxel
    moff: Any  # (R + 1,) first surface-mesh vertex
    foff: Any  # (R + 1,) first surface-mesh triangle
    froff: Any  # (R + 1,) first recorded voxel position (frames x voxels)


class VoxelData(NamedTuple):
    """Per-voxel constants, flat (voxel v of robot r at voff[r] + v)."""

    flags: Any  # FLAG_FIXED | FLAG_ACTIVE
    cos_phase: Any
    sin_phase: Any
    phase: Any  # radians
    vc: Any  # (N_VCONST per voxel) mass, damping, floor stiffness, frequency, weight
    ext: Any  # (3 per voxel) external force
    vlink: Any  # (6 per voxel) link on each face, local (-1: none)
    exposed: Any  # bit f: face f exposed
    fstart: Any  # the voxel's first surface-mesh triangle (``mesh_face`` order)
    fcount: Any  # its triangles
    surf_of: Any  # its place among the robot's surface voxels (-1: none)


class LinkData(NamedTuple):
    """Per-link constants, flat (link j of robot r at loff[r] + j)."""

    neg: Any  # voxel on the negative side, local
    pos: Any  # voxel on the positive side
    axis: Any  # 0 x, 1 y, 2 z
    stiff: Any  # E_link / E_ref
    damp: Any  # bond damping gamma_link / (2 dt)


class ContactData(NamedTuple):
    """The self-contact candidates (the policy: ``sim.physics``), per surface voxel."""

    surface: Any  # surface voxels, local, by robot (soff)
    near: Any  # (width per voxel) voxels never in contact (-1 pads)
    near_width: Any  # (1,) the width of ``near``'s rows
    cand: Any  # (MAX_CONTACTS per surface voxel) candidates
    ncand: Any  # candidates in use
    built: Any  # (3 per surface voxel) positions when the list was built


class MeshData(NamedTuple):
    """The surface mesh of the paper's water drag (``sim.system.surface_mesh``)."""

    vert: Any  # (8 per vertex) voxel * 8 + corner of the voxels sharing it (-1 pads)
    face: Any  # (4 per triangle) its vertices and the voxel whose face it covers
    points: Any  # (3 per vertex) the vertices' positions this step


class BodyState(NamedTuple):
    """The robots' state carried from launch to launch, flat."""

    pos: Any  # (3 per voxel) metres
    quat: Any  # (4 per voxel) (w, x, y, z)
    lin_mom: Any  # (3 per voxel)
    ang_mom: Any  # (3 per voxel)
    static: Any  # held by static friction (0 / 1)
    link_state: Any  # (LINK_STATE per link) previous deformation and frame mode


class Scratch(NamedTuple):
    """Per-step values of the robots that run in global memory (``shared=False``)."""

    size: Any  # actuated size per voxel
    force: Any  # (3 per voxel)
    moment: Any  # (3 per voxel)
    loads: Any  # (LINK_LOADS per link) each link's loads in world axes


class Output(NamedTuple):
    """What the host reads back, and the control words it steers the launches with."""

    ctl: Any  # (R, N_CTL) int32: C_RUNNING, C_STEP, C_CODE, C_DONE, C_NCOM
    travel: Any  # (R,) bound on the surface's motion since the candidates were listed
    frames: Any  # (3 per recorded voxel position)
    com: Any  # (R * COM_ROWS * 4) centre-of-mass samples (t, x, y, z)


# ---------------------------------------------------------------- the sub-steps of a step
# Each is run by every thread of a robot's block, thread t of nt taking elements t, t + nt, ...;
# arrays are the robot's own (local indices) unless named otherwise. The kernel puts a block
# sync between them.
@substep
def sample(k, p, t, nt, n, r, VC, pos, frames, frame0, com, n_com):
    """Frames and centre-of-mass samples due at step k (``physics.frame_due``,
    ``physics.com_due``; ``kernels.sample``); returns the samples taken so far. ``com``:
    ``Output.com`` (robot r's rows)."""
    if frame_due(k, p):
        base = frame0 + (k // p.record) * n
        for q in range(t, 3 * n, nt):
            frames[3 * base + q] = pos[q]
    if com_due(k, p, n_com, COM_ROWS):
        if t == 0:
            com[(r * COM_ROWS + n_com) * 4] = k * p.dt
            com_sample(n, VC, pos, com[r * COM_ROWS * 4:(r + 1) * COM_ROWS * 4], n_com)
        n_com += 1
    return n_com


@substep
def actuate(k, p, t, nt, n, FL, VC, phase, cos_phase, sin_phase, size):
    """Every voxel's size at step k (``physics.actuation``, ``physics.voxel_size``;
    ``kernels.actuate_kernel``)."""
    time = (k - p.act_start) * p.dt
    mode, s_wt, c_wt = actuation(p, time)
    for v in range(t, n, nt):
        size[v] = voxel_size(p, mode, time, FL[v] & FLAG_ACTIVE != 0, VC[v * N_VCONST + V_OMEGA],
                             phase[v], cos_phase[v], sin_phase[v], s_wt, c_wt)


def _link_forces(ph, real):
    """The links' sub-step with the physics ``ph`` (``physics.compiled``) in the precision
    ``real`` casts to (float: float64; numpy.float32: the mixed precision, as the numba
    engine's float32 link buffer rounds the same inputs)."""
    # the pieces as plain names: a kernel can close over functions, not over a namespace
    link_geometry, link_frame, reframe = ph.link_geometry, ph.link_frame, ph.reframe
    frame_damping, frame_mode, link_response = ph.frame_damping, ph.frame_mode, ph.link_response

    @substep
    def link_forces(p, t, nt, m, neg, lpos, laxis, lstiff, ldamp, pos, quat, size, ls, loads,
                    flag):
        """Every link's loads in world axes into ``loads`` (``kernels.link_kernel`` and
        ``change_frames``): each link in the co-rotational frame it is in (mode +1 small, -1
        large, 0 new: ``physics.link_frame``), computed again in the other frame when it
        outgrows it (``physics.reframe``), then damped and loaded
        (``physics.link_response``); flag[0] set if a link diverged."""
        L = real(p.L)
        a1, a2, b1, b2, b3 = real(p.a1), real(p.a2), real(p.b1), real(p.b2), real(p.b3)
        for j in range(t, m, nt):
            a, b = neg[j], lpos[j]
            axis = laxis[j]
            rest = real(rest_length(size[a], size[b]))
            R, rx, ry, rz, ow, ox, oy, oz = link_geometry(
                real(quat[4 * a]), real(quat[4 * a + 1]), real(quat[4 * a + 2]),
                real(quat[4 * a + 3]), real(quat[4 * b]), real(quat[4 * b + 1]),
                real(quat[4 * b + 2]), real(quat[4 * b + 3]), real(pos[3 * b] - pos[3 * a]),
                real(pos[3 * b + 1] - pos[3 * a + 1]), real(pos[3 * b + 2] - pos[3 * a + 2]),
                axis)
            S = LINK_STATE * j
            mode = ls[S + 8]
            small = mode >= 0.0
            W, d, change = link_frame(small, R, axis, rx, ry, rz, ow, ox, oy, oz, rest)
            damp = frame_damping(real(mode), real(ldamp[j]))
            kept = frame_mode(small)
            if change:
                W, d, damp, kept = reframe(small, R, axis, rx, ry, rz, ow, ox, oy, oz, rest)
            previous = (real(ls[S]), real(ls[S + 1]), real(ls[S + 2]), real(ls[S + 3]),
                        real(ls[S + 4]), real(ls[S + 5]), real(ls[S + 6]), real(ls[S + 7]))
            out, bad = link_response(damp, W, d, previous, rest,
                                     (real(lstiff[j]), L, a1, a2, b1, b2, b3))
            ls[S], ls[S + 1], ls[S + 2], ls[S + 3], ls[S + 4] = d[0], d[1], d[2], d[3], d[4]
            ls[S + 5], ls[S + 6], ls[S + 7], ls[S + 8] = d[5], d[6], d[7], kept
            O = LINK_LOADS * j
            (loads[O], loads[O + 1], loads[O + 2], loads[O + 3], loads[O + 4], loads[O + 5],
             loads[O + 6], loads[O + 7], loads[O + 8]) = out
            if bad:
                flag[0] = 1.0

    return link_forces


# the links' sub-step of each precision (``sim.models.PRECISIONS``)
LINK_FORCES = {"float64": _link_forces(phys, float), "mixed": _link_forces(phys32, np.float32)}


@substep
def mesh_vertices(p, t, nt, nv, m0, mvert, exposed, pos, quat, size, points):
    """The surface mesh's vertices (``kernels.mesh_vertices_kernel``): each the mean of the
    corners of the voxels that share it (``physics.voxel_corner``), computed per vertex and
    voxel (the CPU engine keeps every voxel's corners instead, for its vector loop; the same
    sums in the same order). ``mvert`` and ``points`` are the batch's (the robot's from
    vertex m0)."""
    for kv in range(t, nv, nt):
        sx, sy, sz, count = 0.0, 0.0, 0.0, 0
        for slot in range(8):
            code8 = mvert[(m0 + kv) * 8 + slot]
            if code8 < 0:
                break
            v, c = code8 >> 3, code8 & 7
            R = rotation_matrix(quat[4 * v], quat[4 * v + 1], quat[4 * v + 2], quat[4 * v + 3])
            cx, cy, cz = voxel_corner(c, pos[3 * v], pos[3 * v + 1], pos[3 * v + 2], R, size[v],
                                      p.L, exposed[v])
            sx, sy, sz = sx + cx, sy + cy, sz + cz
            count += 1
        points[3 * (m0 + kv)] = sx / count
        points[3 * (m0 + kv) + 1] = sy / count
        points[3 * (m0 + kv) + 2] = sz / count


@device
def displacement_range(t, nt, ns, surface, pos, built, c, red):
    """The smallest and the largest axis-c displacement of the surface voxels from ``built``
    (``physics.widen``, as ``kernels.surface_moved``), each thread over its voxels, then by
    two fixed-order trees; every thread of the block calls it."""
    lo, hi = math.inf, -math.inf
    for q in range(t, ns, nt):
        lo, hi = widen(lo, hi, pos[3 * surface[q] + c] - built[3 * q + c])
    red[t] = hi
    cuda.syncthreads()
    tree(red, t, nt, False)
    hi = red[0]
    cuda.syncthreads()
    red[t] = lo
    cuda.syncthreads()
    tree(red, t, nt, True)
    lo = red[0]
    cuda.syncthreads()
    return lo, hi


@substep
def contact_list(p, t, nt, ns, s0, contacts, near, width, pos, red, flag, travel):
    """The self-contact candidates (``kernels.contact_list_kernel``), called once the bound
    ``travel`` is stale (``physics.contacts_stale``): the surface voxels' displacement spread
    is measured (``physics.displacement_spread``), and the list rebuilt if that is stale
    too; each thread lists its surface voxels' candidates (``substeps.is_candidate``) by a
    search over every surface voxel (the CPU engine scans lists of far pairs). flag[2] set if a
    voxel has more than MAX_CONTACTS (the policy). Returns the new bound on half the spread.
    Every thread calls it (it reduces over the block). ``contacts``: the batch's (the robot's
    surface from s0); ``near``: the robot's rows."""
    surface, cand = contacts.surface[s0:s0 + ns], contacts.cand[s0 * MAX_CONTACTS:]
    ncand, built = contacts.ncand[s0:s0 + ns], contacts.built[3 * s0:3 * (s0 + ns)]
    lo_x, hi_x = displacement_range(t, nt, ns, surface, pos, built, 0, red)
    lo_y, hi_y = displacement_range(t, nt, ns, surface, pos, built, 1, red)
    lo_z, hi_z = displacement_range(t, nt, ns, surface, pos, built, 2, red)
    travel = displacement_spread(lo_x, hi_x, lo_y, hi_y, lo_z, hi_z)
    if contacts_stale(travel, p.L):
        reach = candidate_radius(p.L, p.contact_reach, p.amp)
        reach2 = reach * reach
        for q in range(t, ns, nt):
            i = surface[q]
            count = 0
            for qq in range(ns):
                j = surface[qq]
                if j == i:
                    continue
                if is_candidate(near, width, i, j, pos[3 * j] - pos[3 * i],
                                pos[3 * j + 1] - pos[3 * i + 1], pos[3 * j + 2] - pos[3 * i + 2],
                                reach2):
                    if count == MAX_CONTACTS:  # the policy: the run stops
                        flag[2] = 1.0
                        break
                    cand[q * MAX_CONTACTS + count] = j
                    count += 1
            ncand[q] = count
            built[3 * q] = pos[3 * i]  # where the list was built from
            built[3 * q + 1] = pos[3 * i + 1]
            built[3 * q + 2] = pos[3 * i + 2]
        travel = 0.0
    return travel


@device
def link_sums(loads, VL, v):
    """Voxel v's force and moment from its links' loads (``physics.voxel_loads``;
    ``kernels.link_sums``); ``VL``: the link on each of its faces (-1: none)."""
    return voxel_loads(face_loads(loads, VL[6 * v + 1]), face_loads(loads, VL[6 * v + 3]),
                       face_loads(loads, VL[6 * v + 5]), face_loads(loads, VL[6 * v]),
                       face_loads(loads, VL[6 * v + 2]), face_loads(loads, VL[6 * v + 4]))


@device
def contact_forces(p, v, first, count, cand, pos, lm, size, VC, fx, fy, fz):
    """The force (fx, fy, fz) plus voxel v's contacts with its ``count`` candidates (from
    ``cand[first]``; ``substeps.pair_force``; ``kernels.contact_forces_kernel``)."""
    for c in range(count):
        touch, px, py, pz = pair_force(pos, lm, size, VC, N_VCONST, v, cand[first + c],
                                       p.contact_reach, p.contact_stiff, p.contact_damp, 3, 1)
        if touch:
            fx, fy, fz = fx - px, fy - py, fz - pz
    return fx, fy, fz


@device
def mesh_drag(p, v, first, count, m0, mface, points, lm, VC, fx, fy, fz):
    """The force (fx, fy, fz) plus the drag on voxel v's ``count`` surface-mesh triangles
    (from ``mface``'s triangle ``first``, their vertices from m0 in ``points``;
    ``physics.facet_force``; ``kernels.mesh_drag_kernel``)."""
    for tri in range(first, first + count):
        va, vb, vc = m0 + mface[4 * tri], m0 + mface[4 * tri + 1], m0 + mface[4 * tri + 2]
        dfx, dfy, dfz = facet_force(
            p.mesh_drag, points[3 * va], points[3 * va + 1], points[3 * va + 2], points[3 * vb],
            points[3 * vb + 1], points[3 * vb + 2], points[3 * vc], points[3 * vc + 1],
            points[3 * vc + 2], lm[3 * v], lm[3 * v + 1], lm[3 * v + 2],
            VC[v * N_VCONST + V_INV_MASS])
        fx, fy, fz = fx + dfx, fy + dfy, fz + dfz
    return fx, fy, fz


@substep
def gather(p, t, nt, n, v0, s0, m0, f0, voxels, contacts, mesh, VC, VL, pos, lm, size, loads,
           force, moment):
    """Each voxel's force and moment, gathered by the voxel itself (no atomics): its links'
    loads (``link_sums``), its self-contacts (``contact_forces``) and the drag on its
    surface-mesh triangles (``mesh_drag``), the sub-steps the CPU engine runs as loops of
    their own. ``voxels``, ``contacts``, ``mesh``: the batch's groups (the robot's from
    voxel v0, surface voxel s0, vertex m0, triangle f0)."""
    surf_of, fstart, fcount = voxels.surf_of, voxels.fstart, voxels.fcount
    cand, ncand, mface, points = contacts.cand, contacts.ncand, mesh.face, mesh.points
    for v in range(t, n, nt):
        fx, fy, fz, mx, my, mz = link_sums(loads, VL, v)
        moment[3 * v], moment[3 * v + 1], moment[3 * v + 2] = mx, my, mz
        q = surf_of[v0 + v]
        if p.collide and q >= 0:
            fx, fy, fz = contact_forces(p, v, (s0 + q) * MAX_CONTACTS, ncand[s0 + q], cand, pos,
                                        lm, size, VC, fx, fy, fz)
        if p.mesh_drag > 0.0:
            fx, fy, fz = mesh_drag(p, v, f0 + fstart[v0 + v], fcount[v0 + v], m0, mface,
                                   points, lm, VC, fx, fy, fz)
        force[3 * v], force[3 * v + 1], force[3 * v + 2] = fx, fy, fz


@substep
def voxel_update(world, t, nt, n, FL, VC, exposed, ext, ST, pos, quat, lm, am, size, force,
                 moment, flag):
    """Every voxel's own forces and its step (``physics.voxel_update``;
    ``kernels.voxel_update_kernel``); returns the largest squared speed of this thread's
    voxels; flag[1] set if one left the sane range."""
    fastest = 0.0
    sane_all = True
    dt = world[0]
    for v in range(t, n, nt):
        c0 = v * N_VCONST
        (x, y, z, qw, qx, qy, qz, px, py, pz, lx, ly, lz, still, touch, v2, sane,
         turn) = voxel_update_of(
            world, (VC[c0 + V_MASS], VC[c0 + V_INV_MASS], VC[c0 + V_INV_INERTIA],
                    VC[c0 + V_CGLIN], VC[c0 + V_CGANG], VC[c0 + V_KFLOOR],
                    VC[c0 + V_CCOLL]), exposed[v], size[v], FL[v] & FLAG_FIXED != 0,
            force[3 * v] + ext[3 * v], force[3 * v + 1] + ext[3 * v + 1],
            force[3 * v + 2] + ext[3 * v + 2], moment[3 * v], moment[3 * v + 1],
            moment[3 * v + 2], pos[3 * v], pos[3 * v + 1], pos[3 * v + 2],
            quat[4 * v], quat[4 * v + 1], quat[4 * v + 2], quat[4 * v + 3],
            lm[3 * v], lm[3 * v + 1], lm[3 * v + 2], am[3 * v], am[3 * v + 1],
            am[3 * v + 2], ST[v] != 0)
        if turn:  # past the series: the exact rotation (``physics.voxel_turn``)
            qw, qx, qy, qz, sane_q = voxel_turn(VC[c0 + V_INV_INERTIA], dt, lx, ly, lz, qw, qx,
                                                qy, qz)
            sane = sane and sane_q
        ST[v] = 1 if still else 0
        pos[3 * v], pos[3 * v + 1], pos[3 * v + 2] = x, y, z
        quat[4 * v], quat[4 * v + 1], quat[4 * v + 2], quat[4 * v + 3] = qw, qx, qy, qz
        lm[3 * v], lm[3 * v + 1], lm[3 * v + 2] = px, py, pz
        am[3 * v], am[3 * v + 1], am[3 * v + 2] = lx, ly, lz
        fastest = max(fastest, v2)
        sane_all = sane_all and sane
    if not sane_all:
        flag[1] = 1.0
    return fastest


@substep
def copy(t, nt, count, src, dst):
    """dst[:count] = src[:count], by the block's threads."""
    for q in range(t, count, nt):
        dst[q] = src[q]


@cache
def rollout_kernel(shared: bool, threads: int, precision: str = "float64"):
    """The rollout kernel with the robot's state in shared memory (``shared``) or global
    memory, for blocks of ``threads`` threads (its reduction scratch is sized for them), its
    links in ``precision`` (``LINK_FORCES``).
    Its arguments: ``chunk`` (steps per launch), ``which`` (the robot of each block) and the
    groups ``Robots``, ``VoxelData``, ``LinkData``, ``ContactData``, ``MeshData``,
    ``BodyState``, ``Scratch``, ``Output`` (``sim.cuda_engine.kernel_inputs`` fills them)."""

    link_forces = LINK_FORCES[precision]

    @cuda.jit
    def rollout(chunk, which, robots, voxels, links, contacts, mesh, body, scratch, out):
        r = which[cuda.blockIdx.x]
        ctl = out.ctl
        if ctl[r, C_RUNNING] == 0:
            return
        t = cuda.threadIdx.x
        nt = cuda.blockDim.x
        # dynamic shared memory: the reductions' scratch, three flags (a link diverged; a voxel
        # left the sane range; a voxel has more contact candidates than MAX_CONTACTS), then
        # the robot's state (``shared``). (No static shared arrays: numba-cuda's simulator
        # can hand two threads of a block different copies of one.)
        dyn = cuda.shared.array(0, float64)
        red = dyn[0:threads]
        flag = dyn[threads:threads + SCRATCH_WORDS]
        base = threads + SCRATCH_WORDS
        voff, loff, soff, moff, foff = robots.voff, robots.loff, robots.soff, robots.moff, robots.foff
        v0, l0, s0, m0, f0 = voff[r], loff[r], soff[r], moff[r], foff[r]
        n, m, ns = voff[r + 1] - v0, loff[r + 1] - l0, soff[r + 1] - s0
        nv = moff[r + 1] - m0
        p = params(robots.fp[r * N_FPARAMS:(r + 1) * N_FPARAMS],
                   robots.ip[r * N_IPARAMS:(r + 1) * N_IPARAMS])
        world = voxel_world(p)

        # this robot's slices (local indices from here on)
        VC = voxels.vc[v0 * N_VCONST:(v0 + n) * N_VCONST]
        FL, EX = voxels.flags[v0:v0 + n], voxels.exposed[v0:v0 + n]
        VL = voxels.vlink[6 * v0:6 * (v0 + n)]
        width = contacts.near_width[0]
        NEAR = contacts.near[v0 * width:(v0 + n) * width]
        ST = body.static[v0:v0 + n]
        if shared:
            own = dyn[base:base + VOXEL_WORDS * n + LINK_WORDS * m]
            pos, quat = own[0:3 * n], own[3 * n:7 * n]
            lm, am = own[7 * n:10 * n], own[10 * n:13 * n]
            size, force, moment = own[13 * n:14 * n], own[14 * n:17 * n], own[17 * n:20 * n]
            ls = own[20 * n:20 * n + LINK_STATE * m]
            loads = own[20 * n + LINK_STATE * m:20 * n + (LINK_STATE + LINK_LOADS) * m]
            copy(t, nt, 3 * n, body.pos[3 * v0:], pos)
            copy(t, nt, 3 * n, body.lin_mom[3 * v0:], lm)
            copy(t, nt, 3 * n, body.ang_mom[3 * v0:], am)
            copy(t, nt, 4 * n, body.quat[4 * v0:], quat)
            copy(t, nt, LINK_STATE * m, body.link_state[LINK_STATE * l0:], ls)
        else:
            pos, quat = body.pos[3 * v0:3 * (v0 + n)], body.quat[4 * v0:4 * (v0 + n)]
            lm, am = body.lin_mom[3 * v0:3 * (v0 + n)], body.ang_mom[3 * v0:3 * (v0 + n)]
            ls = body.link_state[LINK_STATE * l0:LINK_STATE * (l0 + m)]
            size = scratch.size[v0:v0 + n]
            force = scratch.force[3 * v0:3 * (v0 + n)]
            moment = scratch.moment[3 * v0:3 * (v0 + n)]
            loads = scratch.loads[LINK_LOADS * l0:LINK_LOADS * (l0 + m)]
        if t == 0:
            flag[0], flag[1], flag[2] = 0.0, 0.0, 0.0
        cuda.syncthreads()

        k = ctl[r, C_STEP]
        n_com = ctl[r, C_NCOM]
        travel = out.travel[r]
        code, done, finished = 0, p.steps, False
        end = min(k + chunk, p.steps + 1)
        while k < end:
            n_com = sample(k, p, t, nt, n, r, VC, pos, out.frames, robots.froff[r], out.com, n_com)
            if k == p.steps:
                finished = True
                break
            actuate(k, p, t, nt, n, FL, VC, voxels.phase[v0:v0 + n],
                    voxels.cos_phase[v0:v0 + n], voxels.sin_phase[v0:v0 + n], size)
            cuda.syncthreads()
            link_forces(p, t, nt, m, links.neg[l0:l0 + m], links.pos[l0:l0 + m],
                        links.axis[l0:l0 + m], links.stiff[l0:l0 + m], links.damp[l0:l0 + m],
                        pos, quat, size, ls, loads, flag)
            if p.mesh_drag > 0.0:
                mesh_vertices(p, t, nt, nv, m0, mesh.vert, EX, pos, quat, size, mesh.points)
            if p.collide and contacts_stale(travel, p.L):
                travel = contact_list(p, t, nt, ns, s0, contacts, NEAR, width, pos, red, flag,
                                      travel)
            cuda.syncthreads()
            gather(p, t, nt, n, v0, s0, m0, f0, voxels, contacts, mesh, VC, VL, pos, lm, size,
                   loads, force, moment)
            cuda.syncthreads()
            fastest = voxel_update(world, t, nt, n, FL, VC, EX,
                                   voxels.ext[3 * v0:3 * (v0 + n)], ST, pos, quat, lm, am,
                                   size, force, moment, flag)
            if p.collide:
                red[t] = fastest
            cuda.syncthreads()
            if p.collide:
                tree(red, t, nt, False)
                travel = travel_after(travel, red[0], p.dt)
            code = step_status(flag[0] != 0.0, flag[1] != 0.0, flag[2] != 0.0)
            if code != STATUS_OK:
                done, finished = k + 1, True
                break
            k += 1

        cuda.syncthreads()
        if finished:
            if t == 0:  # the final centre of mass is always the last sample
                out.com[(r * COM_ROWS + n_com) * 4] = done * p.dt
                com_sample(n, VC, pos, out.com[r * COM_ROWS * 4:(r + 1) * COM_ROWS * 4], n_com)
                ctl[r, C_RUNNING], ctl[r, C_CODE], ctl[r, C_DONE] = 0, code, done
                ctl[r, C_NCOM] = n_com + 1
        elif t == 0:
            ctl[r, C_STEP], ctl[r, C_NCOM] = k, n_com
            out.travel[r] = travel
        if shared:
            copy(t, nt, 3 * n, pos, body.pos[3 * v0:])
            copy(t, nt, 3 * n, lm, body.lin_mom[3 * v0:])
            copy(t, nt, 3 * n, am, body.ang_mom[3 * v0:])
            copy(t, nt, 4 * n, quat, body.quat[4 * v0:])
            copy(t, nt, LINK_STATE * m, ls, body.link_state[LINK_STATE * l0:])

    return rollout
