"""GPU kernels (numba-cuda): one thread block per robot, many steps per launch.

``rollout_kernel(shared, threads)`` builds the kernel that steps the robots of a batch for up
to ``chunk`` steps, block r for robot ``which[r]``. A block's threads share the robot's
voxels and links (thread t takes voxels t, t + T, ... and links likewise) and meet at block
syncs between the sub-steps of a step, which are those of ``sim.kernels`` and call the same
``sim.physics`` pieces:

    actuate | links (+ surface-mesh vertices, + the self-contact list when it is stale)
    | gather (link sums, contacts, facet drag) | voxel update | reductions

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

from numba import cuda, float64
from numba.cuda import config as cuda_config

from . import physics
from .kernels import COLLIDE_MARGIN
from .system import (
    COM_SAMPLES,
    FLAG_ACTIVE,
    FLAG_FIXED,
    N_FPARAMS,
    N_IPARAMS,
    N_VCONST,
    STATUS_NONFINITE,
    STATUS_STRAIN,
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
MAX_CANDIDATES = 32  # self-contact candidates kept per surface voxel
COM_ROWS = COM_SAMPLES + 3  # rows of a robot's centre-of-mass trajectory
VOXEL_WORDS = 20  # float64 per voxel in shared memory: pos 3, quat 4, momenta 6, size 1, force 3, moment 3
LINK_WORDS = 18  # per link: state 9 (previous deformation 8, frame mode), loads 9
LINK_STATE, LINK_LOADS = 9, 9
SCRATCH_WORDS = 2  # float64 in a block's dynamic shared memory beyond one per thread: the flags
# control words of a robot, ``ctl[r, :]``
C_RUNNING, C_STEP, C_CODE, C_DONE, C_NCOM = range(5)
N_CTL = 5


def _fma_device(a, b, c):
    return cuda.fma(a, b, c)


if SIMULATOR:  # the plain functions: the simulator runs kernels as Python
    def device(f):
        return f

    phys = physics.compiled(device, physics.fma)
else:
    device = cuda.jit(device=True)
    phys = physics.compiled(device, device(_fma_device))

dot3, qrot, rotation_matrix, waveform = phys.dot3, phys.qrot, phys.rotation_matrix, phys.waveform
actuated_size, link_geometry, small_frame = phys.actuated_size, phys.link_geometry, phys.small_frame
large_frame, damped, link_loads = phys.large_frame, phys.damped, phys.link_loads
link_diverged, contact_push, facet_drag = phys.link_diverged, phys.contact_push, phys.facet_drag
contact_overlap = phys.contact_overlap
mesh_corner, voxel_update, voxel_world = phys.mesh_corner, phys.voxel_update, phys.voxel_world
params = device(params_of)


@device
def listed(near, width, i, j):
    """Whether row i of ``near`` (``width`` entries per row) holds j."""
    for q in range(width):
        if near[i * width + q] == j:
            return True
    return False


@device
def link_load(loads, j, q):
    """Row q of the loads of link j; 0 for no link (j < 0)."""
    return loads[j * LINK_LOADS + q] if j >= 0 else 0.0


@device
def face_loads(loads, p0, p1, p2, q0, q1, q2, row_p, row_q, sign):
    """A voxel's sum over its faces of row ``row_p`` of the links it is the negative end of
    (p0, p1, p2: on its +x, +y, +z faces) plus ``sign`` times row ``row_q`` of those it is the
    positive end of (q0, q1, q2), in the order of ``kernels.link_sums``."""
    return ((link_load(loads, p0, row_p) + link_load(loads, p1, row_p) + link_load(loads, p2, row_p))
            + sign * (link_load(loads, q0, row_q) + link_load(loads, q1, row_q)
                      + link_load(loads, q2, row_q)))


@device
def com_sample(n, vc, pos, com, row):
    """The mass-weighted centre of mass into ``com[row, 1:4]`` (one thread; the order of
    ``sim.kernels.com``)."""
    total = 0.0
    for v in range(n):
        total += vc[v * N_VCONST + V_WEIGHT]
    for c in range(3):
        acc = 0.0
        for v in range(n):
            acc += vc[v * N_VCONST + V_WEIGHT] * pos[3 * v + c]
        com[row * 4 + 1 + c] = acc / total


@device
def tree_max(red, t, nt):
    """red[0] = the largest of red[:nt] (NaN-propagating as ``kernels.surface_moved``), by a
    fixed-order tree; every thread of the block calls it."""
    span = 1
    while span < nt:
        span *= 2
    span //= 2
    while span > 0:
        if t < span and t + span < nt:
            a, b = red[t], red[t + span]
            red[t] = b if not (b <= a) else a
        cuda.syncthreads()
        span //= 2


@cache
def rollout_kernel(shared: bool, threads: int):
    """The rollout kernel with the robot's state in shared memory (``shared``) or global
    memory, for blocks of ``threads`` threads (its reduction scratch is sized for them)."""

    @cuda.jit
    def rollout(chunk, which, fp, ip, voff, loff, soff, moff, foff, froff,
                flags, cos_phase, sin_phase, phase, vc, ext, nbr, vlink, exposed, fstart,
                fcount, surf_of, surface, near, near_width, lneg, lpos, laxis, lstiff, ldamp,
                mvert, mface, g_pos, g_quat, g_lm, g_am, static, g_ls, g_size, g_force,
                g_moment, g_loads, vert, cand, ncand, built, ctl, travel_of, frames, com_traj):
        r = which[cuda.blockIdx.x]
        if ctl[r, C_RUNNING] == 0:
            return
        t = cuda.threadIdx.x
        nt = cuda.blockDim.x
        # dynamic shared memory: the reductions' scratch, two flags (a link diverged; a voxel
        # left the sane range), then the robot's state (``shared``). (No static shared
        # arrays: numba-cuda's simulator can hand two threads of a block different copies of
        # one.)
        dyn = cuda.shared.array(0, float64)
        red = dyn[0:threads]
        flag = dyn[threads:threads + 2]
        base = threads + SCRATCH_WORDS
        v0, l0, s0, m0 = voff[r], loff[r], soff[r], moff[r]
        n, m, ns = voff[r + 1] - v0, loff[r + 1] - l0, soff[r + 1] - s0
        nv = moff[r + 1] - m0
        p = params(fp[r * N_FPARAMS:(r + 1) * N_FPARAMS], ip[r * N_IPARAMS:(r + 1) * N_IPARAMS])
        L, dt, amp, omega = p.L, p.dt, p.amp, p.omega
        steps, record, wave, collide = p.steps, p.record, p.wave, p.collide
        world = voxel_world(p)
        margin = COLLIDE_MARGIN * L

        # this robot's slices (local indices from here on)
        VC = vc[v0 * N_VCONST:(v0 + n) * N_VCONST]
        FL, NB, VL = flags[v0:v0 + n], nbr[6 * v0:6 * (v0 + n)], vlink[6 * v0:6 * (v0 + n)]
        NEAR = near[v0 * near_width:(v0 + n) * near_width]
        ST = static[v0:v0 + n]
        if shared:
            own = dyn[base:base + VOXEL_WORDS * n + LINK_WORDS * m]
            pos, quat = own[0:3 * n], own[3 * n:7 * n]
            lm, am = own[7 * n:10 * n], own[10 * n:13 * n]
            size, force, moment = own[13 * n:14 * n], own[14 * n:17 * n], own[17 * n:20 * n]
            ls = own[20 * n:20 * n + LINK_STATE * m]
            loads = own[20 * n + LINK_STATE * m:20 * n + (LINK_STATE + LINK_LOADS) * m]
            for q in range(t, 3 * n, nt):
                pos[q], lm[q], am[q] = g_pos[3 * v0 + q], g_lm[3 * v0 + q], g_am[3 * v0 + q]
            for q in range(t, 4 * n, nt):
                quat[q] = g_quat[4 * v0 + q]
            for q in range(t, LINK_STATE * m, nt):
                ls[q] = g_ls[LINK_STATE * l0 + q]
        else:
            pos, quat = g_pos[3 * v0:3 * (v0 + n)], g_quat[4 * v0:4 * (v0 + n)]
            lm, am = g_lm[3 * v0:3 * (v0 + n)], g_am[3 * v0:3 * (v0 + n)]
            size = g_size[v0:v0 + n]
            force, moment = g_force[3 * v0:3 * (v0 + n)], g_moment[3 * v0:3 * (v0 + n)]
            ls = g_ls[LINK_STATE * l0:LINK_STATE * (l0 + m)]
            loads = g_loads[LINK_LOADS * l0:LINK_LOADS * (l0 + m)]
        if t == 0:
            flag[0], flag[1] = 0.0, 0.0
        cuda.syncthreads()

        k = ctl[r, C_STEP]
        n_com = ctl[r, C_NCOM]
        travel = travel_of[r]
        code, done, finished = 0, steps, False
        end = min(k + chunk, steps + 1)
        while k < end:
            if record > 0 and k % record == 0:
                base = froff[r] + (k // record) * n
                for q in range(t, 3 * n, nt):
                    frames[3 * base + q] = pos[q]
            after = k - p.settle_steps
            if after >= 0 and after % p.com_every == 0 and n_com < COM_ROWS - 1:
                if t == 0:
                    com_traj[(r * COM_ROWS + n_com) * 4] = k * dt
                    com_sample(n, VC, pos, com_traj[r * COM_ROWS * 4:(r + 1) * COM_ROWS * 4], n_com)
                n_com += 1
            if k == steps:
                finished = True
                break

            # actuate (``kernels.actuate``)
            time = (k - p.act_start) * dt
            s_wt, c_wt = math.sin(omega * time), math.cos(omega * time)
            for v in range(t, n, nt):
                size[v] = L
                if time >= 0.0 and FL[v] & FLAG_ACTIVE:
                    if p.freq_field:
                        w = waveform(wave, VC[v * N_VCONST + V_OMEGA] * time + phase[v0 + v])
                    elif wave == 0:  # sin(wt + phi) without libm per voxel
                        w = s_wt * cos_phase[v0 + v] + c_wt * sin_phase[v0 + v]
                    else:
                        w = waveform(wave, omega * time + phase[v0 + v])
                    size[v] = actuated_size(L, amp, w)
            cuda.syncthreads()

            # link_forces, first half (``kernels.link_kernel`` and ``change_frames``): each link
            # in the co-rotational frame it is in (mode +1 small, -1 large, 0 new)
            for j in range(t, m, nt):
                a, b = lneg[l0 + j], lpos[l0 + j]
                axis = laxis[l0 + j]
                rest = 0.5 * (size[a] + size[b])
                R, rx, ry, rz, ow, ox, oy, oz = link_geometry(
                    quat[4 * a], quat[4 * a + 1], quat[4 * a + 2], quat[4 * a + 3],
                    quat[4 * b], quat[4 * b + 1], quat[4 * b + 2], quat[4 * b + 3],
                    pos[3 * b] - pos[3 * a], pos[3 * b + 1] - pos[3 * a + 1],
                    pos[3 * b + 2] - pos[3 * a + 2], axis)
                mode = ls[LINK_STATE * j + 8]
                damp = ldamp[l0 + j]
                if mode >= 0.0:
                    W, dx, dy, dz, t1y, t1z, t2x, t2y, t2z, leave = small_frame(
                        R, axis, rx, ry, rz, ow, ox, oy, oz, rest)
                    damp = damp if mode != 0.0 else 0.0
                    mode = 1.0
                    if leave:  # computed again in the other frame, undamped
                        W, dx, dy, dz, t1y, t1z, t2x, t2y, t2z, back = large_frame(
                            R, axis, rx, ry, rz, ow, ox, oy, oz, rest)
                        damp, mode = 0.0, -1.0
                else:
                    W, dx, dy, dz, t1y, t1z, t2x, t2y, t2z, back = large_frame(
                        R, axis, rx, ry, rz, ow, ox, oy, oz, rest)
                    mode = -1.0
                    if back:
                        W, dx, dy, dz, t1y, t1z, t2x, t2y, t2z, leave = small_frame(
                            R, axis, rx, ry, rz, ow, ox, oy, oz, rest)
                        damp, mode = 0.0, 1.0
                S = LINK_STATE * j
                ex, ey, ez = damped(damp, dx, ls[S]), damped(damp, dy, ls[S + 1]), damped(damp, dz, ls[S + 2])
                e1y, e1z = damped(damp, t1y, ls[S + 3]), damped(damp, t1z, ls[S + 4])
                e2x, e2y = damped(damp, t2x, ls[S + 5]), damped(damp, t2y, ls[S + 6])
                e2z = damped(damp, t2z, ls[S + 7])
                ls[S], ls[S + 1], ls[S + 2], ls[S + 3], ls[S + 4] = dx, dy, dz, t1y, t1z
                ls[S + 5], ls[S + 6], ls[S + 7], ls[S + 8] = t2x, t2y, t2z, mode
                O = LINK_LOADS * j
                (loads[O], loads[O + 1], loads[O + 2], loads[O + 3], loads[O + 4], loads[O + 5],
                 loads[O + 6], loads[O + 7], loads[O + 8]) = link_loads(
                    W, lstiff[l0 + j], rest, L, p.a1, p.a2, p.b1, p.b2, p.b3, ex, ey, ez, e1y, e1z, e2x,
                    e2y, e2z)
                if link_diverged(dx, rest):
                    flag[0] = 1.0
            # mesh drag, first half (``kernels.mesh_drag_kernel``): surface-mesh vertices, the
            # mean of the corners of the voxels that share each
            if p.mesh_drag > 0.0:
                for kv in range(t, nv, nt):
                    sx, sy, sz, count = 0.0, 0.0, 0.0, 0
                    for slot in range(8):
                        code8 = mvert[(m0 + kv) * 8 + slot]
                        if code8 < 0:
                            break
                        v, c = code8 >> 3, code8 & 7
                        r00, r01, r02, r10, r11, r12, r20, r21, r22 = rotation_matrix(
                            quat[4 * v], quat[4 * v + 1], quat[4 * v + 2], quat[4 * v + 3])
                        ox, oy, oz = mesh_corner(c, size[v], L, NB[6 * v + ((c >> 2) & 1)] >= 0,
                                                 NB[6 * v + 2 + ((c >> 1) & 1)] >= 0,
                                                 NB[6 * v + 4 + (c & 1)] >= 0)
                        sx += pos[3 * v] + dot3(r00, r01, r02, ox, oy, oz)
                        sy += pos[3 * v + 1] + dot3(r10, r11, r12, ox, oy, oz)
                        sz += pos[3 * v + 2] + dot3(r20, r21, r22, ox, oy, oz)
                        count += 1
                    vert[3 * (m0 + kv)] = sx / count
                    vert[3 * (m0 + kv) + 1] = sy / count
                    vert[3 * (m0 + kv) + 2] = sz / count
            # collide, first half (``kernels.collide_kernel``): the self-contact candidates,
            # rebuilt once surface voxels may have closed half the margin and did
            if collide and 2.0 * travel >= margin:
                most = 0.0
                for q in range(t, ns, nt):
                    v = surface[s0 + q]
                    dx = pos[3 * v] - built[3 * (s0 + q)]
                    dy = pos[3 * v + 1] - built[3 * (s0 + q) + 1]
                    dz = pos[3 * v + 2] - built[3 * (s0 + q) + 2]
                    d2 = dx * dx + dy * dy + dz * dz
                    most = d2 if not (d2 <= most) else most
                red[t] = most
                cuda.syncthreads()
                tree_max(red, t, nt)
                travel = math.sqrt(red[0])
                cuda.syncthreads()
                if not (2.0 * travel < margin):
                    reach = 2.0 * p.contact_reach * L * (1.0 + amp) + margin
                    reach2 = reach * reach
                    for q in range(t, ns, nt):
                        i = surface[s0 + q]
                        count = 0
                        for qq in range(ns):
                            j = surface[s0 + qq]
                            if j == i:
                                continue
                            dx = pos[3 * j] - pos[3 * i]
                            dy = pos[3 * j + 1] - pos[3 * i + 1]
                            dz = pos[3 * j + 2] - pos[3 * i + 2]
                            if (dx * dx + dy * dy + dz * dz < reach2
                                    and not listed(NEAR, near_width, i, j)
                                    and count < MAX_CANDIDATES):
                                cand[(s0 + q) * MAX_CANDIDATES + count] = j
                                count += 1
                        ncand[s0 + q] = count
                        built[3 * (s0 + q)] = pos[3 * i]  # where the list was built from
                        built[3 * (s0 + q) + 1] = pos[3 * i + 1]
                        built[3 * (s0 + q) + 2] = pos[3 * i + 2]
                    travel = 0.0
            cuda.syncthreads()

            # the second halves, gathered per voxel: link_forces' sums (``kernels.link_sums``),
            # collide's contacts and the mesh drag's facets
            for v in range(t, n, nt):
                p0, p1, p2 = VL[6 * v + 1], VL[6 * v + 3], VL[6 * v + 5]  # v the negative end
                q0, q1, q2 = VL[6 * v], VL[6 * v + 2], VL[6 * v + 4]  # v the positive end
                fx = face_loads(loads, p0, p1, p2, q0, q1, q2, 0, 0, -1.0)
                fy = face_loads(loads, p0, p1, p2, q0, q1, q2, 1, 1, -1.0)
                fz = face_loads(loads, p0, p1, p2, q0, q1, q2, 2, 2, -1.0)
                moment[3 * v] = face_loads(loads, p0, p1, p2, q0, q1, q2, 3, 6, 1.0)
                moment[3 * v + 1] = face_loads(loads, p0, p1, p2, q0, q1, q2, 4, 7, 1.0)
                moment[3 * v + 2] = face_loads(loads, p0, p1, p2, q0, q1, q2, 5, 8, 1.0)
                q = surf_of[v0 + v]
                if collide and q >= 0:
                    inv_mv = VC[v * N_VCONST + V_INV_MASS]
                    for c in range(ncand[s0 + q]):
                        j = cand[(s0 + q) * MAX_CANDIDATES + c]
                        dx = pos[3 * j] - pos[3 * v]
                        dy = pos[3 * j + 1] - pos[3 * v + 1]
                        dz = pos[3 * j + 2] - pos[3 * v + 2]
                        overlap, dist = contact_overlap(dx, dy, dz, size[v], size[j], p.contact_reach)
                        if overlap <= 0.0 or dist == 0.0:
                            continue
                        inv_mj = VC[j * N_VCONST + V_INV_MASS]
                        px, py, pz = contact_push(
                            overlap, dist, dx, dy, dz, lm[3 * j] * inv_mj - lm[3 * v] * inv_mv,
                            lm[3 * j + 1] * inv_mj - lm[3 * v + 1] * inv_mv,
                            lm[3 * j + 2] * inv_mj - lm[3 * v + 2] * inv_mv,
                            VC[v * N_VCONST + V_KFLOOR], VC[j * N_VCONST + V_KFLOOR],
                            VC[v * N_VCONST + V_CCOLL], VC[j * N_VCONST + V_CCOLL],
                            p.contact_stiff, p.contact_damp)
                        fx, fy, fz = fx - px, fy - py, fz - pz
                if p.mesh_drag > 0.0:
                    for tri in range(fstart[v0 + v], fstart[v0 + v] + fcount[v0 + v]):
                        va, vb, vcn = (m0 + mface[4 * tri], m0 + mface[4 * tri + 1],
                                       m0 + mface[4 * tri + 2])
                        ux = vert[3 * vb] - vert[3 * va]
                        uy = vert[3 * vb + 1] - vert[3 * va + 1]
                        uz = vert[3 * vb + 2] - vert[3 * va + 2]
                        wx = vert[3 * vcn] - vert[3 * va]
                        wy = vert[3 * vcn + 1] - vert[3 * va + 1]
                        wz = vert[3 * vcn + 2] - vert[3 * va + 2]
                        nx, ny, nz = uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx
                        dfx, dfy, dfz = facet_drag(
                            p.mesh_drag, lm[3 * v] * nx + lm[3 * v + 1] * ny + lm[3 * v + 2] * nz,
                            VC[v * N_VCONST + V_INV_MASS], nx, ny, nz)
                        fx, fy, fz = fx + dfx, fy + dfy, fz + dfz
                force[3 * v], force[3 * v + 1], force[3 * v + 2] = fx, fy, fz
            cuda.syncthreads()

            # voxel_update (``kernels.voxel_kernel``): every voxel's own forces and its step
            fastest = 0.0
            sane_all = True
            for v in range(t, n, nt):
                if FL[v] & FLAG_FIXED:
                    lm[3 * v], lm[3 * v + 1], lm[3 * v + 2] = 0.0, 0.0, 0.0
                    am[3 * v], am[3 * v + 1], am[3 * v + 2] = 0.0, 0.0, 0.0
                    continue
                c0 = v * N_VCONST
                e = 3 * (v0 + v)
                (x, y, z, qw, qx, qy, qz, px, py, pz, lx, ly, lz, still, touch, v2,
                 sane) = voxel_update(
                    world, (VC[c0 + V_MASS], VC[c0 + V_INV_MASS], VC[c0 + V_INV_INERTIA],
                            VC[c0 + V_CGLIN], VC[c0 + V_CGANG], VC[c0 + V_KFLOOR],
                            VC[c0 + V_CCOLL]), exposed[v0 + v], size[v],
                    force[3 * v] + ext[e], force[3 * v + 1] + ext[e + 1],
                    force[3 * v + 2] + ext[e + 2], moment[3 * v], moment[3 * v + 1],
                    moment[3 * v + 2], pos[3 * v], pos[3 * v + 1], pos[3 * v + 2],
                    quat[4 * v], quat[4 * v + 1], quat[4 * v + 2], quat[4 * v + 3],
                    lm[3 * v], lm[3 * v + 1], lm[3 * v + 2], am[3 * v], am[3 * v + 1],
                    am[3 * v + 2], ST[v] != 0)
                ST[v] = 1 if still else 0
                pos[3 * v], pos[3 * v + 1], pos[3 * v + 2] = x, y, z
                quat[4 * v], quat[4 * v + 1], quat[4 * v + 2], quat[4 * v + 3] = qw, qx, qy, qz
                lm[3 * v], lm[3 * v + 1], lm[3 * v + 2] = px, py, pz
                am[3 * v], am[3 * v + 1], am[3 * v + 2] = lx, ly, lz
                fastest = max(fastest, v2)
                sane_all = sane_all and sane
            if not sane_all:
                flag[1] = 1.0
            if collide:
                red[t] = fastest
            cuda.syncthreads()
            if collide:
                tree_max(red, t, nt)
                travel = travel + math.sqrt(max(red[0], 0.0)) * dt
            if flag[0] != 0.0:
                code, done, finished = STATUS_STRAIN, k + 1, True
                break
            if flag[1] != 0.0:
                code, done, finished = STATUS_NONFINITE, k + 1, True
                break
            k += 1

        cuda.syncthreads()
        if finished:
            if t == 0:  # the final centre of mass is always the last sample
                com_traj[(r * COM_ROWS + n_com) * 4] = done * dt
                com_sample(n, VC, pos, com_traj[r * COM_ROWS * 4:(r + 1) * COM_ROWS * 4], n_com)
                ctl[r, C_RUNNING], ctl[r, C_CODE], ctl[r, C_DONE] = 0, code, done
                ctl[r, C_NCOM] = n_com + 1
        elif t == 0:
            ctl[r, C_STEP], ctl[r, C_NCOM] = k, n_com
            travel_of[r] = travel
        if shared:
            for q in range(t, 3 * n, nt):
                g_pos[3 * v0 + q], g_lm[3 * v0 + q], g_am[3 * v0 + q] = pos[q], lm[q], am[q]
            for q in range(t, 4 * n, nt):
                g_quat[4 * v0 + q] = quat[q]
            for q in range(t, LINK_STATE * m, nt):
                g_ls[LINK_STATE * l0 + q] = ls[q]

    return rollout
