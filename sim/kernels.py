"""Compiled kernels: the whole rollout of many robots in one call.

Each robot's run is one task of a ``prange`` over robots; inside it a step is, in order:
``actuate -> clear -> link forces -> self-collisions -> voxel forces + integrate -> record``.
All state is struct-of-arrays (see ``sim.system``); no Python runs per voxel or per step.

Maths conventions: quaternions are (w, x, y, z); a link's local frame has x along the link
(see ``_to_link``); rotation vectors are axis * angle in radians.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from sim.system import (
    F_A1,
    F_A2,
    F_AMP,
    F_B1,
    F_B2,
    F_B3,
    F_CCOLL,
    F_CGANG,
    F_CGLIN,
    F_DRAG,
    F_DT,
    F_GAMMA,
    F_GRAVITY,
    F_INERTIA,
    F_KFLOOR,
    F_L,
    F_MASS,
    F_MUK,
    F_MUS,
    F_OMEGA,
    FLAG_ACTIVE,
    FLAG_FIXED,
    I_COLLIDE,
    I_COM_EVERY,
    I_ENV,
    I_RECORD,
    I_SETTLE_STEPS,
    I_STEPS,
    I_WAVE,
)

# fastmath without 'nnan'/'ninf' (divergence stays detectable by comparisons) and without
# 'reassoc'/'contract': with those, a freshly compiled kernel and the same kernel loaded from
# numba's cache round differently, and the same seed must give the same run in every process.
FASTMATH = {"arcp", "nsz", "afn"}
JIT = dict(cache=True, fastmath=FASTMATH, error_model="numpy")
INLINE = dict(inline="always", **JIT)

STATUS_OK, STATUS_STRAIN, STATUS_NONFINITE = 0, 1, 2
MAX_STRAIN = 100.0  # axial strain of a link beyond which the run is declared diverged
POSITION_BOUND = 1.0e4  # metres: anything beyond is a blow-up (also catches NaN)
SMALL_TURN, SMALL_EXTEND, HYSTERESIS = 0.05, 0.5, 1.2
COLLIDE_EVERY = 8  # steps between refreshes of the self-collision candidate pairs
FRICTION_EPS = 1e-9  # horizontal speeds below this many voxel lengths per step count as 0
MIN_SIZE = 0.1  # smallest actuated size, as a fraction of the voxel size


# ---------------------------------------------------------------- quaternion helpers
@njit(**INLINE)
def qmul(aw, ax, ay, az, bw, bx, by, bz):
    """Hamilton product a * b."""
    return (
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    )


@njit(**INLINE)
def qrot(w, x, y, z, vx, vy, vz):
    """Rotate vector v by the unit quaternion (w, x, y, z)."""
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    return (
        vx + w * tx + (y * tz - z * ty),
        vy + w * ty + (z * tx - x * tz),
        vz + w * tz + (x * ty - y * tx),
    )


@njit(**INLINE)
def rotvec(w, x, y, z):
    """Rotation vector (axis * angle) of a unit quaternion; a series for small angles."""
    if w < 0.0:
        w, x, y, z = -w, -x, -y, -z
    s2 = x * x + y * y + z * z
    if s2 < 0.04 * w * w:  # |v| / w < 0.2 (angle < 0.39 rad): atan series, rel. error < 1e-8
        inv_w = 1.0 / w
        r2 = s2 * inv_w * inv_w
        f = 2.0 * inv_w * (1.0 - r2 * (1.0 / 3.0 - r2 * (0.2 - r2 * (1.0 / 7.0 - r2 / 9.0))))
    else:
        s = math.sqrt(s2)
        f = 2.0 * math.atan2(s, w) / s
    return f * x, f * y, f * z


@njit(**INLINE)
def quat_from_rotvec(px, py, pz):
    """Unit quaternion of the rotation vector p (series when the angle is small)."""
    a2 = 0.25 * (px * px + py * py + pz * pz)  # (half angle)^2
    if a2 < 1e-2:
        c = 1.0 - a2 * (0.5 - a2 / 24.0)
        f = 0.5 * (1.0 - a2 * (1.0 / 6.0 - a2 / 120.0))
    else:
        h = math.sqrt(a2)
        c = math.cos(h)
        f = math.sin(h) / (2.0 * h)
    return c, f * px, f * py, f * pz


@njit(**INLINE)
def to_link(axis, x, y, z):
    """Proper rotation taking the world axis ``axis`` (0 x, 1 y, 2 z) onto +x."""
    if axis == 0:
        return x, y, z
    if axis == 1:
        return y, -x, z
    return z, y, -x


@njit(**INLINE)
def from_link(axis, x, y, z):
    """Inverse of ``to_link``."""
    if axis == 0:
        return x, y, z
    if axis == 1:
        return -y, x, z
    return -z, y, x


# ---------------------------------------------------------------- actuation
@njit(**INLINE)
def waveform(kind, angle):
    """Periodic actuation signal in [-1, 1] of phase angle (radians).

    0 sine; 1 square (smoothed: tanh(8 sin)/tanh(8), so steps are resolvable by the lattice);
    2 impulse: fast contraction over the first 20% of the cycle, slow release over the rest.
    """
    if kind == 0:
        return math.sin(angle)
    if kind == 1:
        return math.tanh(8.0 * math.sin(angle)) / math.tanh(8.0)
    u = angle / (2.0 * math.pi)
    u = u - math.floor(u)
    if u < 0.2:
        return math.cos(math.pi * u / 0.2)
    return -math.cos(math.pi * (u - 0.2) / 0.8)


@njit(**JIT)
def actuate(v0, v1, t, fp, wave, flags, cos_phase, sin_phase, phase, size):
    """Current size of every voxel of one robot at time t (t < 0: no actuation yet)."""
    L = fp[F_L]
    if t < 0.0:
        for v in range(v0, v1):
            size[v] = L
        return
    amp = fp[F_AMP]
    wt = fp[F_OMEGA] * t
    s_wt, c_wt = math.sin(wt), math.cos(wt)
    for v in range(v0, v1):
        if flags[v] & FLAG_ACTIVE:
            if wave == 0:  # sin(wt + phi) without libm per voxel
                w = s_wt * cos_phase[v] + c_wt * sin_phase[v]
            else:
                w = waveform(wave, wt + phase[v])
            size[v] = max(L * (1.0 + amp * w), MIN_SIZE * L)
        else:
            size[v] = L


# ---------------------------------------------------------------- links
@njit(**INLINE)
def link_force(l, link_neg, link_pos, link_axis, pos, quat, size, small, prev, prev_valid,
               force, moment, a1, a2, b1, b2, b3, damp, inv_l):
    """Beam forces of link l, added to both ends. Returns |elongation| - MAX_STRAIN * rest.

    Co-rotational: the frame follows the negative-side voxel while the bend is small and the
    centre-to-centre line when it is large (hysteresis as Voxelyze). Bond damping is
    stiffness-proportional: the beam sees d + damp * (change of d per step), which gives every
    beam term the damping coefficient 2 zeta sqrt(m k).
    """
    i = link_neg[l]
    j = link_pos[l]
    ax = link_axis[l]
    qw, qx, qy, qz = quat[i, 0], quat[i, 1], quat[i, 2], quat[i, 3]
    # rotation matrix of the negative voxel (world = R local), cheaper than repeated qrot
    r00 = 1.0 - 2.0 * (qy * qy + qz * qz)
    r01 = 2.0 * (qx * qy - qw * qz)
    r02 = 2.0 * (qx * qz + qw * qy)
    r10 = 2.0 * (qx * qy + qw * qz)
    r11 = 1.0 - 2.0 * (qx * qx + qz * qz)
    r12 = 2.0 * (qy * qz - qw * qx)
    r20 = 2.0 * (qx * qz - qw * qy)
    r21 = 2.0 * (qy * qz + qw * qx)
    r22 = 1.0 - 2.0 * (qx * qx + qy * qy)
    wx, wy, wz = pos[j, 0] - pos[i, 0], pos[j, 1] - pos[i, 1], pos[j, 2] - pos[i, 2]
    rx = r00 * wx + r10 * wy + r20 * wz
    ry = r01 * wx + r11 * wy + r21 * wz
    rz = r02 * wx + r12 * wy + r22 * wz
    ow, ox, oy, oz = qmul(qw, -qx, -qy, -qz, quat[j, 0], quat[j, 1], quat[j, 2], quat[j, 3])
    rx, ry, rz = to_link(ax, rx, ry, rz)
    ox, oy, oz = to_link(ax, ox, oy, oz)
    rest = 0.5 * (size[i] + size[j])

    # hysteresis between the two frames, compared without divisions
    turn = abs(ry) + abs(rz)  # compared against SMALL_TURN * rx
    extend = abs(rx - rest)  # compared against SMALL_EXTEND * rest
    if small[l]:
        if turn > SMALL_TURN * rx or extend > SMALL_EXTEND * rest:
            small[l] = False
            prev_valid[l] = False
    elif (turn < (SMALL_TURN / HYSTERESIS) * rx
          and extend < (SMALL_EXTEND / HYSTERESIS) * rest):
        small[l] = True
        prev_valid[l] = False

    if small[l]:
        dx, dy, dz = rx - rest, ry, rz
        t1x, t1y, t1z = 0.0, 0.0, 0.0
        t2x, t2y, t2z = rotvec(ow, ox, oy, oz)
        cw, cx, cy, cz = 1.0, 0.0, 0.0, 0.0
    else:
        length = math.sqrt(rx * rx + ry * ry + rz * rz)
        inv_length = 1.0 / length
        ux, uy, uz = rx * inv_length, ry * inv_length, rz * inv_length
        if ux > -0.9999:  # rotation taking u onto +x, by the half-angle identity
            cw, cx, cy, cz = 1.0 + ux, 0.0, uz, -uy
            norm = 1.0 / math.sqrt(cw * cw + cy * cy + cz * cz)
            cw, cy, cz = cw * norm, cy * norm, cz * norm
        else:
            cw, cx, cy, cz = 0.0, 0.0, 0.0, 1.0
        dx, dy, dz = length - rest, 0.0, 0.0
        t1x, t1y, t1z = rotvec(cw, cx, cy, cz)
        pw, px, py, pz = qmul(cw, cx, cy, cz, ow, ox, oy, oz)
        t2x, t2y, t2z = rotvec(pw, px, py, pz)

    # stiffness-proportional damping from the change since the last step
    ex, ey, ez = dx, dy, dz
    e1x, e1y, e1z, e2x, e2y, e2z = t1x, t1y, t1z, t2x, t2y, t2z
    if prev_valid[l]:
        ex += damp * (dx - prev[l, 0])
        ey += damp * (dy - prev[l, 1])
        ez += damp * (dz - prev[l, 2])
        e1x += damp * (t1x - prev[l, 3])
        e1y += damp * (t1y - prev[l, 4])
        e1z += damp * (t1z - prev[l, 5])
        e2x += damp * (t2x - prev[l, 6])
        e2y += damp * (t2y - prev[l, 7])
        e2z += damp * (t2z - prev[l, 8])
    prev[l, 0], prev[l, 1], prev[l, 2] = dx, dy, dz
    prev[l, 3], prev[l, 4], prev[l, 5] = t1x, t1y, t1z
    prev[l, 6], prev[l, 7], prev[l, 8] = t2x, t2y, t2z
    prev_valid[l] = True

    # 3-D frame element (Euler-Bernoulli), forces and moments on the negative end (a) and the
    # moments on the positive end (b); the force on b is -fa.
    fax = a1 * ex * (rest * inv_l)  # E A_current strain: area and rest length both scale
    fay = b1 * ey - b2 * (e1z + e2z)
    faz = b1 * ez + b2 * (e1y + e2y)
    max_ = a2 * (e2x - e1x)
    may = -b2 * ez - b3 * (2.0 * e1y + e2y)
    maz = b2 * ey - b3 * (2.0 * e1z + e2z)
    mby = -b2 * ez - b3 * (e1y + 2.0 * e2y)
    mbz = b2 * ey - b3 * (e1z + 2.0 * e2z)

    mbx = -max_
    if not small[l]:  # undo the large-angle alignment: rotate by conj(c), c = (cw, 0, cy, cz)
        c00 = 1.0 - 2.0 * (cy * cy + cz * cz)
        c01, c02 = 2.0 * cw * cz, -2.0 * cw * cy
        c11, c12 = 1.0 - 2.0 * cz * cz, 2.0 * cy * cz
        c22 = 1.0 - 2.0 * cy * cy
        fax, fay, faz = (c00 * fax + c01 * fay + c02 * faz, -c01 * fax + c11 * fay + c12 * faz,
                         -c02 * fax + c12 * fay + c22 * faz)
        max_, may, maz = (c00 * max_ + c01 * may + c02 * maz, -c01 * max_ + c11 * may + c12 * maz,
                          -c02 * max_ + c12 * may + c22 * maz)
        mbx, mby, mbz = (c00 * mbx + c01 * mby + c02 * mbz, -c01 * mbx + c11 * mby + c12 * mbz,
                         -c02 * mbx + c12 * mby + c22 * mbz)
    # back to world axes: undo the axis permutation, then the voxel frame
    fx, fy, fz = from_link(ax, fax, fay, faz)
    fax = r00 * fx + r01 * fy + r02 * fz
    fay = r10 * fx + r11 * fy + r12 * fz
    faz = r20 * fx + r21 * fy + r22 * fz
    fx, fy, fz = from_link(ax, max_, may, maz)
    max_ = r00 * fx + r01 * fy + r02 * fz
    may = r10 * fx + r11 * fy + r12 * fz
    maz = r20 * fx + r21 * fy + r22 * fz
    fx, fy, fz = from_link(ax, mbx, mby, mbz)
    mbx = r00 * fx + r01 * fy + r02 * fz
    mby = r10 * fx + r11 * fy + r12 * fz
    mbz = r20 * fx + r21 * fy + r22 * fz

    force[i, 0] += fax
    force[i, 1] += fay
    force[i, 2] += faz
    force[j, 0] -= fax
    force[j, 1] -= fay
    force[j, 2] -= faz
    moment[i, 0] += max_
    moment[i, 1] += may
    moment[i, 2] += maz
    moment[j, 0] += mbx
    moment[j, 1] += mby
    moment[j, 2] += mbz
    return abs(dx) - MAX_STRAIN * rest  # > 0: diverged


@njit(**JIT)
def link_forces(l0, l1, fp, link_neg, link_pos, link_axis, pos, quat, size, small, prev,
                prev_valid, force, moment):
    """Add the forces of links l0..l1 of one robot; return the largest excess of |axial
    strain| over MAX_STRAIN (times rest length): > 0, or NaN, means diverged."""
    damp = fp[F_GAMMA] * 0.5 / fp[F_DT]
    a1, a2, b1, b2, b3 = fp[F_A1], fp[F_A2], fp[F_B1], fp[F_B2], fp[F_B3]
    inv_l = 1.0 / fp[F_L]
    worst = -1e300
    for l in range(l0, l1):
        excess = link_force(l, link_neg, link_pos, link_axis, pos, quat, size, small, prev,
                            prev_valid, force, moment, a1, a2, b1, b2, b3, damp, inv_l)
        if excess > worst or excess != excess:  # a NaN sticks
            worst = excess
    return worst


# ---------------------------------------------------------------- self-collisions
@njit(**INLINE)
def bonded(nbr, i, j):
    for k in range(6):
        if nbr[i, k] == j:
            return True
    return False


@njit(**JIT)
def collision_pairs(s0, s1, p0, p1, surface, pos, nbr, reach, pairs):
    """Candidate pairs of unbonded surface voxels closer than ``reach`` (sweep along x)."""
    ns = s1 - s0
    xs = np.empty(ns)
    for a in range(ns):
        xs[a] = pos[surface[s0 + a], 0]
    order = np.argsort(xs)
    count = 0
    cap = p1 - p0
    reach2 = reach * reach
    for a in range(ns):
        i = surface[s0 + order[a]]
        for b in range(a + 1, ns):
            j = surface[s0 + order[b]]
            dx = pos[j, 0] - pos[i, 0]
            if dx > reach:
                break
            dy = pos[j, 1] - pos[i, 1]
            dz = pos[j, 2] - pos[i, 2]
            if dx * dx + dy * dy + dz * dz < reach2 and not bonded(nbr, i, j):
                if count < cap:
                    pairs[p0 + count, 0] = i
                    pairs[p0 + count, 1] = j
                    count += 1
    return count


@njit(**JIT)
def collision_forces(p0, count, pairs, pos, lin_mom, size, fp, force):
    """Penalty contact between unbonded voxels: equal and opposite, so momentum is kept."""
    k = fp[F_KFLOOR]  # harmonic mean of the two voxels' 2 E L: the same for one material
    c = fp[F_CCOLL]
    inv_m = 1.0 / fp[F_MASS]
    for q in range(p0, p0 + count):
        i, j = pairs[q, 0], pairs[q, 1]
        dx = pos[j, 0] - pos[i, 0]
        dy = pos[j, 1] - pos[i, 1]
        dz = pos[j, 2] - pos[i, 2]
        dist = math.sqrt(dx * dx + dy * dy + dz * dz)
        overlap = 0.5 * (size[i] + size[j]) - dist
        if overlap <= 0.0 or dist == 0.0:
            continue
        nx, ny, nz = dx / dist, dy / dist, dz / dist
        vn = ((lin_mom[j, 0] - lin_mom[i, 0]) * nx + (lin_mom[j, 1] - lin_mom[i, 1]) * ny
              + (lin_mom[j, 2] - lin_mom[i, 2]) * nz) * inv_m
        f = max(k * overlap - c * vn, 0.0)
        force[j, 0] += f * nx
        force[j, 1] += f * ny
        force[j, 2] += f * nz
        force[i, 0] -= f * nx
        force[i, 1] -= f * ny
        force[i, 2] -= f * nz


# ---------------------------------------------------------------- voxels
@njit(**JIT)
def integrate(v0, v1, fp, env, flags, ext_force, nbr, size, static, force, moment, pos, quat,
              lin_mom, ang_mom):
    """World forces (gravity, damping, floor and friction, drag) and one semi-implicit Euler
    step for voxels v0..v1. Returns False if any voxel left the sane range (or went NaN)."""
    m, inertia, dt = fp[F_MASS], fp[F_INERTIA], fp[F_DT]
    inv_m, inv_i = 1.0 / m, 1.0 / inertia
    g, k_floor, c_coll = fp[F_GRAVITY], fp[F_KFLOOR], fp[F_CCOLL]
    c_lin, c_ang, mu_s, mu_k, drag = fp[F_CGLIN], fp[F_CGANG], fp[F_MUS], fp[F_MUK], fp[F_DRAG]
    ok = True
    for v in range(v0, v1):
        if flags[v] & FLAG_FIXED:
            lin_mom[v, 0] = lin_mom[v, 1] = lin_mom[v, 2] = 0.0
            ang_mom[v, 0] = ang_mom[v, 1] = ang_mom[v, 2] = 0.0
            continue
        vx, vy, vz = lin_mom[v, 0] * inv_m, lin_mom[v, 1] * inv_m, lin_mom[v, 2] * inv_m
        fx = force[v, 0] + ext_force[v, 0] - c_lin * vx
        fy = force[v, 1] + ext_force[v, 1] - c_lin * vy
        fz = force[v, 2] + ext_force[v, 2] - c_lin * vz - m * g
        mx = moment[v, 0] - c_ang * ang_mom[v, 0] * inv_i
        my = moment[v, 1] - c_ang * ang_mom[v, 1] * inv_i
        mz = moment[v, 2] - c_ang * ang_mom[v, 2] * inv_i
        qw, qx, qy, qz = quat[v, 0], quat[v, 1], quat[v, 2], quat[v, 3]

        if env == 1 and drag > 0.0:  # water: quadratic drag on exposed faces moving outward
            area = size[v] * size[v]
            for a in range(3):
                ex, ey, ez = qrot(qw, qx, qy, qz, 1.0 if a == 0 else 0.0,
                                  1.0 if a == 1 else 0.0, 1.0 if a == 2 else 0.0)
                for side in range(2):
                    if nbr[v, 2 * a + side] >= 0:
                        continue
                    sgn = 1.0 if side == 1 else -1.0
                    vn = sgn * (vx * ex + vy * ey + vz * ez)
                    if vn > 0.0:
                        f = -drag * area * vn * vn * sgn
                        fx += f * ex
                        fy += f * ey
                        fz += f * ez

        in_contact = False
        if env == 0:  # land: penalty floor at z = 0, static and kinetic friction
            pen = 0.5 * size[v] - pos[v, 2]
            if pen >= 0.0:
                in_contact = True
                normal = k_floor * pen
                fz += normal - c_coll * vz
                if static[v] and fx * fx + fy * fy > (mu_s * normal) ** 2:
                    static[v] = False
                elif not static[v]:
                    hv = math.sqrt(vx * vx + vy * vy)
                    if hv > FRICTION_EPS * fp[F_L] / dt:
                        fx -= mu_k * normal * vx / hv
                        fy -= mu_k * normal * vy / hv
            else:
                static[v] = False
        lin_mom[v, 2] += fz * dt
        px, py = lin_mom[v, 0] + fx * dt, lin_mom[v, 1] + fy * dt
        if in_contact:  # a sliding voxel sticks when friction would reverse it (work-energy)
            work = (fx * px + fy * py) * inv_m * dt
            if 0.5 * inv_m * (px * px + py * py) + work <= 0.0:
                static[v] = True
            if static[v]:
                px, py = 0.0, 0.0
        lin_mom[v, 0], lin_mom[v, 1] = px, py
        pos[v, 0] += lin_mom[v, 0] * inv_m * dt
        pos[v, 1] += lin_mom[v, 1] * inv_m * dt
        pos[v, 2] += lin_mom[v, 2] * inv_m * dt

        ang_mom[v, 0] += mx * dt
        ang_mom[v, 1] += my * dt
        ang_mom[v, 2] += mz * dt
        dw, dx, dy, dz = quat_from_rotvec(ang_mom[v, 0] * inv_i * dt, ang_mom[v, 1] * inv_i * dt,
                                          ang_mom[v, 2] * inv_i * dt)
        qw, qx, qy, qz = qmul(dw, dx, dy, dz, qw, qx, qy, qz)
        norm = 1.0 / math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
        quat[v, 0], quat[v, 1], quat[v, 2], quat[v, 3] = qw * norm, qx * norm, qy * norm, qz * norm
        if not (abs(pos[v, 0]) < POSITION_BOUND and abs(pos[v, 1]) < POSITION_BOUND
                and abs(pos[v, 2]) < POSITION_BOUND and abs(qw) <= 1.0 + 1e-9):
            ok = False
    return ok


# ---------------------------------------------------------------- the rollout
@njit(**JIT)
def com(v0, v1, pos, out, row):
    """Centre of mass (one material: the mean position) of voxels v0..v1 into out[row, 1:4]."""
    n = v1 - v0
    for c in range(3):
        acc = 0.0
        for v in range(v0, v1):
            acc += pos[v, c]
        out[row, 1 + c] = acc / n


@njit(**JIT)
def run_robot(r, batch, state, work, frames, com_traj, com_count, status, steps_done):
    """Run robot r of the batch to its step count or to divergence."""
    voff, loff, soff, poff = batch.voff, batch.loff, batch.soff, batch.poff
    v0, v1, l0, l1 = voff[r], voff[r + 1], loff[r], loff[r + 1]
    s0, s1, p0, p1 = soff[r], soff[r + 1], poff[r], poff[r + 1]
    fp, ip = batch.fparams[r], batch.iparams[r]
    pos, quat, lin_mom, ang_mom = state.pos, state.quat, state.lin_mom, state.ang_mom
    size, force, moment, static, small, prev, prev_valid, pairs = work
    dt, steps, settle = fp[F_DT], ip[I_STEPS], ip[I_SETTLE_STEPS]
    env, wave, record, collide = ip[I_ENV], ip[I_WAVE], ip[I_RECORD], ip[I_COLLIDE]
    com_every = ip[I_COM_EVERY]
    reach = 1.5 * fp[F_L] * (1.0 + fp[F_AMP])
    n_pairs = 0
    n_com = 0
    for step in range(steps + 1):
        if record > 0 and step % record == 0:
            f = step // record
            for v in range(v0, v1):
                for c in range(3):
                    frames[f, v, c] = pos[v, c]
        if step >= settle and (step - settle) % com_every == 0 and n_com < com_traj.shape[1] - 1:
            com_traj[r, n_com, 0] = step * dt
            com(v0, v1, pos, com_traj[r], n_com)
            n_com += 1
        if step == steps:
            break
        actuate(v0, v1, (step - settle) * dt, fp, wave, batch.flags, batch.cos_phase,
                batch.sin_phase, batch.phase, size)
        for v in range(v0, v1):
            for c in range(3):
                force[v, c] = 0.0
                moment[v, c] = 0.0
        worst = link_forces(l0, l1, fp, batch.link_neg, batch.link_pos, batch.link_axis, pos,
                            quat, size, small, prev, prev_valid, force, moment)
        if collide:
            if step % COLLIDE_EVERY == 0:
                n_pairs = collision_pairs(s0, s1, p0, p1, batch.surface, pos, batch.nbr, reach,
                                          pairs)
            collision_forces(p0, n_pairs, pairs, pos, lin_mom, size, fp, force)
        ok = integrate(v0, v1, fp, env, batch.flags, batch.ext_force, batch.nbr, size, static,
                       force, moment, pos, quat, lin_mom, ang_mom)
        if not worst <= 0.0:  # also true for NaN
            status[r] = STATUS_STRAIN
            steps_done[r] = step + 1
            break
        if not ok:
            status[r] = STATUS_NONFINITE
            steps_done[r] = step + 1
            break
        steps_done[r] = step + 1
    # always keep the final centre of mass as the last sample
    com_traj[r, n_com, 0] = steps_done[r] * dt
    com(v0, v1, pos, com_traj[r], n_com)
    com_count[r] = n_com + 1


@njit(parallel=True, **JIT)
def run_batch(batch, state, work, frames, com_traj, com_count, status, steps_done):
    """Run every robot of the batch, one robot per parallel task."""
    for r in prange(len(batch.voff) - 1):
        run_robot(r, batch, state, work, frames, com_traj, com_count, status, steps_done)
