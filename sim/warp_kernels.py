"""The Warp engine's kernels: ``sim.kernels``' model, one thread per link or voxel of a batch.

``build(scalar)`` compiles (once per precision, in a Warp module of its own) the five kernels
a step needs, all over flat struct-of-arrays buffers holding every robot of the batch:

    links     one thread per link: co-rotational beam forces into ``link_out`` (as
              ``kernels.link_kernel``: both frames, hysteresis, bond damping), marks the
              robot when a link's strain diverges;
    forces    one thread per voxel: sums its links' forces (``kernels.link_sums``), rebuilds
              its self-collision candidates when the robot's travel says so and adds the
              contact forces (``kernels.collide_kernel``), then gravity, external force,
              global damping, water drag and, on land, floor and friction (the forces
              of ``kernels.voxel_kernel``);
    integrate one thread per voxel: semi-implicit Euler (the step of
              ``kernels.voxel_kernel``),
              the robot's largest speed by atomic max, then the voxel's actuated size for
              the next step (``kernels.actuate_kernel``);
    robots    one thread per robot: after a step, its status (strain, non-finite), the
              collision travel, then the top of the next step of ``kernels.run_robot``:
              frames, centre-of-mass samples, the end of its run;
    actuate   the sizes of the first step (once per run).

A robot's constants are its rows of ``Batch.fparams``/``Batch.iparams`` (columns ``F_*`` and
``I_*`` of ``sim.system``), read by robot index; per-voxel constants are ``vconst`` rows.
Voxel and link indices are global (robot offsets added by ``sim.warp_engine``). A robot that
is done (its steps run, or diverged) has ``running = 0`` and its threads return at once: the
batch is never re-packed. Each robot counts its own steps (``step``), so the step loop needs
no launch argument that changes and replays as a CUDA graph.

Self-collision candidates are kept per voxel (at most ``MAX_CANDIDATES`` partners each)
rather than as the numba engine's list of pairs; both are every unbonded surface pair within
the reach at the same rebuild steps, so the forces are the same up to the order of a sum.
"""

# no ``from __future__ import annotations``: Warp reads the kernels' annotations, which name
# the closure's scalar type
import warp as wp

from .kernels import (
    ANGLE_OVER_SIN,
    COLLIDE_MARGIN,
    FRICTION_EPS,
    HYSTERESIS,
    MAX_STRAIN,
    MIN_SIZE,
    POSITION_BOUND,
    SMALL_EXTEND,
    SMALL_TURN,
    STATUS_NONFINITE,
    STATUS_OK,
    STATUS_STRAIN,
)
from .system import (
    ENV_LAND,
    ENV_WATER,
    F_A1,
    F_A2,
    F_AMP,
    F_B1,
    F_B2,
    F_B3,
    F_DRAG,
    F_DT,
    F_GRAVITY,
    F_L,
    F_MUK,
    F_MUS,
    F_OMEGA,
    FLAG_ACTIVE,
    FLAG_FIXED,
    I_COLLIDE,
    I_COM_EVERY,
    I_ENV,
    I_FREQ_FIELD,
    I_RECORD,
    I_SETTLE_STEPS,
    I_STEPS,
    I_WAVE,
    V_CCOLL,
    V_CGANG,
    V_CGLIN,
    V_INV_INERTIA,
    V_INV_MASS,
    V_KFLOOR,
    V_MASS,
    V_OMEGA,
    V_WEIGHT,
)

MAX_CANDIDATES = 24  # self-collision partners kept per surface voxel
PI = 3.141592653589793
SMALL_TURN_IN, SMALL_EXTEND_IN = SMALL_TURN / HYSTERESIS, SMALL_EXTEND / HYSTERESIS
QUAT_BOUND = 1.0 + 1e-9
C0, C1, C2, C3, C4, C5, C6, C7, C8, C9, C10, C11, C12, C13, C14, C15, C16 = ANGLE_OVER_SIN

_BUILT: dict = {}  # precision -> Kernels


class Kernels:
    """The compiled kernels of one precision (attributes named as in the module docstring)."""

    def __init__(self, scalar, links, forces, integrate, robots, actuate) -> None:
        self.scalar = scalar
        self.links, self.forces, self.integrate = links, forces, integrate
        self.robots, self.actuate = robots, actuate


def build(precision: str) -> Kernels:
    """The kernels for ``precision`` ("float64" or "float32"), defined once per process."""
    if precision not in _BUILT:
        _BUILT[precision] = _define(wp.float64 if precision == "float64" else wp.float32)
    return _BUILT[precision]


def _define(S) -> Kernels:  # noqa: C901 (one closure per precision holds every kernel)
    module = f"softevo_sim_warp_{S.__name__}"
    F = wp.array(dtype=S)
    F2 = wp.array2d(dtype=S)
    F3 = wp.array3d(dtype=S)
    I = wp.array(dtype=wp.int32)  # noqa: E741
    I2 = wp.array2d(dtype=wp.int32)

    # ------------------------------------------------------------ quaternion helpers
    @wp.func
    def qmul(aw: S, ax: S, ay: S, az: S, bw: S, bx: S, by: S, bz: S):
        return (
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        )

    @wp.func
    def qrot(w: S, x: S, y: S, z: S, vx: S, vy: S, vz: S):
        tx = S(2.0) * (y * vz - z * vy)
        ty = S(2.0) * (z * vx - x * vz)
        tz = S(2.0) * (x * vy - y * vx)
        return (
            vx + w * tx + (y * tz - z * ty),
            vy + w * ty + (z * tx - x * tz),
            vz + w * tz + (x * ty - y * tx),
        )

    @wp.func
    def angle_over_sin(u: S):
        u2 = u * u
        u4 = u2 * u2
        u8 = u4 * u4
        lo = (
            (S(C0) + S(C1) * u)
            + u2 * (S(C2) + S(C3) * u)
            + u4 * ((S(C4) + S(C5) * u) + u2 * (S(C6) + S(C7) * u))
        )
        hi = (
            (S(C8) + S(C9) * u)
            + u2 * (S(C10) + S(C11) * u)
            + u4 * ((S(C12) + S(C13) * u) + u2 * (S(C14) + S(C15) * u))
        )
        return lo + u8 * (hi + u8 * S(C16))

    @wp.func
    def rotvec(w: S, x: S, y: S, z: S):
        f = angle_over_sin(S(1.0) - wp.abs(w))
        if w < S(0.0):
            f = -f
        return f * x, f * y, f * z

    @wp.func
    def quat_from_rotvec(px: S, py: S, pz: S):
        a2 = S(0.25) * (px * px + py * py + pz * pz)
        c = S(0.0)
        f = S(0.0)
        if a2 < S(1e-2):
            c = S(1.0) - a2 * (S(0.5) - a2 / S(24.0))
            f = S(0.5) * (S(1.0) - a2 * (S(1.0) / S(6.0) - a2 / S(120.0)))
        else:
            h = wp.sqrt(a2)
            c = wp.cos(h)
            f = wp.sin(h) / (S(2.0) * h)
        return c, f * px, f * py, f * pz

    @wp.func
    def rotation_matrix(w: S, x: S, y: S, z: S):
        return (
            S(1.0) - S(2.0) * (y * y + z * z),
            S(2.0) * (x * y - w * z),
            S(2.0) * (x * z + w * y),
            S(2.0) * (x * y + w * z),
            S(1.0) - S(2.0) * (x * x + z * z),
            S(2.0) * (y * z - w * x),
            S(2.0) * (x * z - w * y),
            S(2.0) * (y * z + w * x),
            S(1.0) - S(2.0) * (x * x + y * y),
        )

    @wp.func
    def to_link(axis: int, x: S, y: S, z: S):
        a = x
        b = y
        c = z
        if axis == 1:
            a = y
            b = -x
        elif axis == 2:
            a = z
            c = -x
        return a, b, c

    # ------------------------------------------------------------ actuation
    @wp.func
    def waveform(kind: int, angle: S):
        out = S(0.0)
        if kind == 0:
            out = wp.sin(angle)
        elif kind == 1:
            out = wp.tanh(S(8.0) * wp.sin(angle)) / wp.tanh(S(8.0))
        else:
            u = angle / (S(2.0) * S(PI))
            u = u - wp.floor(u)
            if u < S(0.2):
                out = wp.cos(S(PI) * u / S(0.2))
            else:
                out = -wp.cos(S(PI) * (u - S(0.2)) / S(0.8))
        return out

    @wp.func
    def voxel_size(
        v: int, r: int, k: int, fp: F2, ip: I2, flags: I, cos_phase: F, sin_phase: F, phase: F, vc: F2
    ):
        """Size of voxel v (robot r) at step k (``kernels.actuate_kernel``)."""
        L = fp[r, F_L]
        t = S(k - ip[r, I_SETTLE_STEPS]) * fp[r, F_DT]
        size = L
        if t >= S(0.0) and (flags[v] & FLAG_ACTIVE) != 0:
            amp = fp[r, F_AMP]
            wave = ip[r, I_WAVE]
            w = S(0.0)
            if ip[r, I_FREQ_FIELD] != 0:
                w = waveform(wave, vc[v, V_OMEGA] * t + phase[v])
            else:
                wt = fp[r, F_OMEGA] * t
                if wave == 0:
                    w = wp.sin(wt) * cos_phase[v] + wp.cos(wt) * sin_phase[v]
                else:
                    w = waveform(wave, wt + phase[v])
            size = wp.max(L * (S(1.0) + amp * w), S(MIN_SIZE) * L)
        return size

    @wp.kernel(module=module, enable_backward=False)
    def actuate(
        running: I,
        robot: I,
        step: I,
        fp: F2,
        ip: I2,
        flags: I,
        cos_phase: F,
        sin_phase: F,
        phase: F,
        vc: F2,
        size: F,
    ):
        v = wp.tid()
        r = robot[v]
        if running[r] == 0:
            return
        size[v] = voxel_size(v, r, step[r], fp, ip, flags, cos_phase, sin_phase, phase, vc)

    # ------------------------------------------------------------ links
    @wp.kernel(module=module, enable_backward=False)
    def links(
        running: I,
        link_robot: I,
        fp: F2,
        link_neg: I,
        link_pos: I,
        link_axis: I,
        link_stiff: F,
        link_damp: F,
        pos: F2,
        quat: F2,
        size: F,
        link_state: F2,
        link_out: F2,
        bad: I,
    ):
        j = wp.tid()
        r = link_robot[j]
        if running[r] == 0:
            return
        i = link_neg[j]
        k = link_pos[j]
        ax = link_axis[j]
        qw = quat[i, 0]
        qx = quat[i, 1]
        qy = quat[i, 2]
        qz = quat[i, 3]
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = rotation_matrix(qw, qx, qy, qz)
        wx = pos[k, 0] - pos[i, 0]
        wy = pos[k, 1] - pos[i, 1]
        wz = pos[k, 2] - pos[i, 2]
        rx, ry, rz = to_link(
            ax, r00 * wx + r10 * wy + r20 * wz, r01 * wx + r11 * wy + r21 * wz, r02 * wx + r12 * wy + r22 * wz
        )
        ow, ox0, oy0, oz0 = qmul(qw, -qx, -qy, -qz, quat[k, 0], quat[k, 1], quat[k, 2], quat[k, 3])
        ox, oy, oz = to_link(ax, ox0, oy0, oz0)
        rest = S(0.5) * (size[i] + size[k])

        turn = wp.abs(ry) + wp.abs(rz)
        extend = wp.abs(rx - rest)
        leave = turn > S(SMALL_TURN) * rx or extend > S(SMALL_EXTEND) * rest
        enter = turn < S(SMALL_TURN_IN) * rx and extend < S(SMALL_EXTEND_IN) * rest
        mode = link_state[j, 9]
        was_small = mode >= S(0.0)
        now_small = enter
        if was_small:
            now_small = not leave
        g = S(0.0)
        if mode != S(0.0) and now_small == was_small:
            g = link_damp[j]
        if now_small:
            link_state[j, 9] = S(1.0)
        else:
            link_state[j, 9] = S(-1.0)

        length = wp.sqrt(rx * rx + ry * ry + rz * rz)
        h = length + rx
        cw = S(0.0)
        cy = S(0.0)
        cz = S(1.0)
        kk = S(1.0)
        if h > S(1e-4) * length:
            cw = h
            cy = rz
            cz = -ry
            kk = S(1.0) / wp.sqrt(S(2.0) * length * h)
        pw, px, py, pz = qmul(cw, S(0.0), cy, cz, ow, ox, oy, oz)
        cw = cw * kk
        cy = cy * kk
        cz = cz * kk
        t1x, t1y, t1z = rotvec(cw, S(0.0), cy, cz)
        lx, ly, lz = rotvec(pw * kk, px * kk, py * kk, pz * kk)
        dx = length - rest
        dy = S(0.0)
        dz = S(0.0)
        t2x = lx
        t2y = ly
        t2z = lz
        if now_small:
            dx = rx - rest
            dy = ry
            dz = rz
            t1x = S(0.0)
            t1y = S(0.0)
            t1z = S(0.0)
            t2x, t2y, t2z = rotvec(ow, ox, oy, oz)
            cw = S(1.0)
            cy = S(0.0)
            cz = S(0.0)

        # world from the beam's frame (``kernels.from_link_matrix``, then conj(c))
        m00 = r00
        m01 = r01
        m02 = r02
        m10 = r10
        m11 = r11
        m12 = r12
        m20 = r20
        m21 = r21
        m22 = r22
        if ax == 1:
            m00 = r01
            m01 = -r00
            m10 = r11
            m11 = -r10
            m20 = r21
            m21 = -r20
        elif ax == 2:
            m00 = r02
            m02 = -r00
            m10 = r12
            m12 = -r10
            m20 = r22
            m22 = -r20
        c00 = S(1.0) - S(2.0) * (cy * cy + cz * cz)
        c01 = S(2.0) * cw * cz
        c02 = S(-2.0) * cw * cy
        c11 = S(1.0) - S(2.0) * cz * cz
        c12 = S(2.0) * cy * cz
        c22 = S(1.0) - S(2.0) * cy * cy
        n00 = m00 * c00 - m01 * c01 - m02 * c02
        n01 = m00 * c01 + m01 * c11 + m02 * c12
        n02 = m00 * c02 + m01 * c12 + m02 * c22
        n10 = m10 * c00 - m11 * c01 - m12 * c02
        n11 = m10 * c01 + m11 * c11 + m12 * c12
        n12 = m10 * c02 + m11 * c12 + m12 * c22
        n20 = m20 * c00 - m21 * c01 - m22 * c02
        n21 = m20 * c01 + m21 * c11 + m22 * c12
        n22 = m20 * c02 + m21 * c12 + m22 * c22

        ex = dx + g * (dx - link_state[j, 0])
        ey = dy + g * (dy - link_state[j, 1])
        ez = dz + g * (dz - link_state[j, 2])
        e1x = t1x + g * (t1x - link_state[j, 3])
        e1y = t1y + g * (t1y - link_state[j, 4])
        e1z = t1z + g * (t1z - link_state[j, 5])
        e2x = t2x + g * (t2x - link_state[j, 6])
        e2y = t2y + g * (t2y - link_state[j, 7])
        e2z = t2z + g * (t2z - link_state[j, 8])
        link_state[j, 0] = dx
        link_state[j, 1] = dy
        link_state[j, 2] = dz
        link_state[j, 3] = t1x
        link_state[j, 4] = t1y
        link_state[j, 5] = t1z
        link_state[j, 6] = t2x
        link_state[j, 7] = t2y
        link_state[j, 8] = t2z

        s = link_stiff[j]
        a1 = fp[r, F_A1] * s
        a2 = fp[r, F_A2] * s
        b1 = fp[r, F_B1] * s
        b2 = fp[r, F_B2] * s
        b3 = fp[r, F_B3] * s
        exs = ex * rest * (S(1.0) / fp[r, F_L])
        fax = a1 * exs
        fay = b1 * ey - b2 * (e1z + e2z)
        faz = b1 * ez + b2 * (e1y + e2y)
        max_ = a2 * (e2x - e1x)
        may = -b2 * ez - b3 * (S(2.0) * e1y + e2y)
        maz = b2 * ey - b3 * (S(2.0) * e1z + e2z)
        mbx = -max_
        mby = -b2 * ez - b3 * (e1y + S(2.0) * e2y)
        mbz = b2 * ey - b3 * (e1z + S(2.0) * e2z)
        link_out[j, 0] = n00 * fax + n01 * fay + n02 * faz
        link_out[j, 1] = n10 * fax + n11 * fay + n12 * faz
        link_out[j, 2] = n20 * fax + n21 * fay + n22 * faz
        link_out[j, 3] = n00 * max_ + n01 * may + n02 * maz
        link_out[j, 4] = n10 * max_ + n11 * may + n12 * maz
        link_out[j, 5] = n20 * max_ + n21 * may + n22 * maz
        link_out[j, 6] = n00 * mbx + n01 * mby + n02 * mbz
        link_out[j, 7] = n10 * mbx + n11 * mby + n12 * mbz
        link_out[j, 8] = n20 * mbx + n21 * mby + n22 * mbz
        if not (wp.abs(dx) <= S(MAX_STRAIN) * rest):  # NaN counts as diverged
            bad[r] = 1

    # ------------------------------------------------------------ voxels
    @wp.kernel(module=module, enable_backward=False)
    def forces(
        running: I,
        robot: I,
        fp: F2,
        ip: I2,
        flags: I,
        vc: F2,
        ext_force: F2,
        nbr: I2,
        vlink: I2,
        surface: I,
        soff: I,
        is_surface: I,
        travel: F,
        cand: I2,
        ncand: I,
        link_out: F2,
        pos: F2,
        quat: F2,
        lin_mom: F2,
        ang_mom: F2,
        size: F,
        force: F2,
        moment: F2,
        stuck: I,
        contact: I,
    ):
        v = wp.tid()
        r = robot[v]
        if running[r] == 0:
            return
        fx = S(0.0)
        fy = S(0.0)
        fz = S(0.0)
        mx = S(0.0)
        my = S(0.0)
        mz = S(0.0)
        for a in range(3):  # ``kernels.link_sums``
            p = vlink[v, 2 * a + 1]
            n = vlink[v, 2 * a]
            if p >= 0:
                fx += link_out[p, 0]
                fy += link_out[p, 1]
                fz += link_out[p, 2]
                mx += link_out[p, 3]
                my += link_out[p, 4]
                mz += link_out[p, 5]
            if n >= 0:
                fx -= link_out[n, 0]
                fy -= link_out[n, 1]
                fz -= link_out[n, 2]
                mx += link_out[n, 6]
                my += link_out[n, 7]
                mz += link_out[n, 8]

        L = fp[r, F_L]
        if ip[r, I_COLLIDE] != 0 and is_surface[v] != 0:  # ``kernels.collide_kernel``
            margin = S(COLLIDE_MARGIN) * L
            if S(2.0) * travel[r] >= margin:
                reach = L * (S(1.0) + fp[r, F_AMP]) + margin
                reach2 = reach * reach
                count = wp.int32(0)  # a dynamic variable (mutated in the loop)
                for q in range(soff[r], soff[r + 1]):
                    u = surface[q]
                    ddx = pos[u, 0] - pos[v, 0]
                    ddy = pos[u, 1] - pos[v, 1]
                    ddz = pos[u, 2] - pos[v, 2]
                    bonded = (
                        u == v
                        or nbr[v, 0] == u
                        or nbr[v, 1] == u
                        or nbr[v, 2] == u
                        or nbr[v, 3] == u
                        or nbr[v, 4] == u
                        or nbr[v, 5] == u
                    )
                    if ddx * ddx + ddy * ddy + ddz * ddz < reach2 and not bonded:
                        if count < MAX_CANDIDATES:
                            cand[v, count] = u
                            count += 1
                ncand[v] = count
            kv = vc[v, V_KFLOOR]
            cv = vc[v, V_CCOLL]
            inv_mv = vc[v, V_INV_MASS]
            for q in range(ncand[v]):
                u = cand[v, q]
                ku = vc[u, V_KFLOOR]
                kc = kv
                if ku != kv:
                    kc = S(2.0) * kv * ku / (kv + ku)
                cc = S(0.5) * (cv + vc[u, V_CCOLL])
                inv_mu = vc[u, V_INV_MASS]
                ddx = pos[u, 0] - pos[v, 0]
                ddy = pos[u, 1] - pos[v, 1]
                ddz = pos[u, 2] - pos[v, 2]
                dist = wp.sqrt(ddx * ddx + ddy * ddy + ddz * ddz)
                overlap = S(0.5) * (size[v] + size[u]) - dist
                if overlap > S(0.0) and dist != S(0.0):
                    nx = ddx / dist
                    ny = ddy / dist
                    nz = ddz / dist
                    vn = (
                        (lin_mom[u, 0] * inv_mu - lin_mom[v, 0] * inv_mv) * nx
                        + (lin_mom[u, 1] * inv_mu - lin_mom[v, 1] * inv_mv) * ny
                        + (lin_mom[u, 2] * inv_mu - lin_mom[v, 2] * inv_mv) * nz
                    )
                    fc = wp.max(kc * overlap - cc * vn, S(0.0))
                    fx = fx - fc * nx
                    fy = fy - fc * ny
                    fz = fz - fc * nz

        if (flags[v] & FLAG_FIXED) == 0:  # world forces of ``kernels.voxel_kernel``
            m = vc[v, V_MASS]
            inv_m = vc[v, V_INV_MASS]
            inv_i = vc[v, V_INV_INERTIA]
            c_lin = vc[v, V_CGLIN]
            c_ang = vc[v, V_CGANG]
            vx = lin_mom[v, 0] * inv_m
            vy = lin_mom[v, 1] * inv_m
            vz = lin_mom[v, 2] * inv_m
            fx = fx + ext_force[v, 0] - c_lin * vx
            fy = fy + ext_force[v, 1] - c_lin * vy
            fz = fz + ext_force[v, 2] - c_lin * vz - m * fp[r, F_GRAVITY]
            mx = mx - c_ang * ang_mom[v, 0] * inv_i
            my = my - c_ang * ang_mom[v, 1] * inv_i
            mz = mz - c_ang * ang_mom[v, 2] * inv_i
            drag = fp[r, F_DRAG]
            env = ip[r, I_ENV]
            if env == ENV_WATER and drag > S(0.0):
                qw = quat[v, 0]
                qx = quat[v, 1]
                qy = quat[v, 2]
                qz = quat[v, 3]
                area = size[v] * size[v]
                for a in range(3):
                    e0 = S(0.0)
                    e1 = S(0.0)
                    e2 = S(0.0)
                    if a == 0:
                        e0 = S(1.0)
                    elif a == 1:
                        e1 = S(1.0)
                    else:
                        e2 = S(1.0)
                    ex, ey, ez = qrot(qw, qx, qy, qz, e0, e1, e2)
                    for side in range(2):
                        if nbr[v, 2 * a + side] < 0:
                            sgn = S(-1.0)
                            if side == 1:
                                sgn = S(1.0)
                            vn = sgn * (vx * ex + vy * ey + vz * ez)
                            if vn > S(0.0):
                                fd = -drag * area * vn * vn * sgn
                                fx += fd * ex
                                fy += fd * ey
                                fz += fd * ez
            if env == ENV_LAND:  # floor of ``kernels.voxel_kernel``
                pen = S(0.5) * size[v] - pos[v, 2]
                if pen >= S(0.0):
                    contact[v] = 1
                    normal = vc[v, V_KFLOOR] * pen
                    fz += normal - vc[v, V_CCOLL] * vz
                    mu_s_n = fp[r, F_MUS] * normal
                    if stuck[v] != 0 and fx * fx + fy * fy > mu_s_n * mu_s_n:
                        stuck[v] = 0
                    elif stuck[v] == 0:
                        hv = wp.sqrt(vx * vx + vy * vy)
                        if hv > S(FRICTION_EPS) * L / fp[r, F_DT]:
                            fx = fx - fp[r, F_MUK] * normal * vx / hv
                            fy = fy - fp[r, F_MUK] * normal * vy / hv
                else:
                    contact[v] = 0
                    stuck[v] = 0
        force[v, 0] = fx
        force[v, 1] = fy
        force[v, 2] = fz
        moment[v, 0] = mx
        moment[v, 1] = my
        moment[v, 2] = mz

    @wp.kernel(module=module, enable_backward=False)
    def integrate(
        running: I,
        robot: I,
        step: I,
        fp: F2,
        ip: I2,
        flags: I,
        cos_phase: F,
        sin_phase: F,
        phase: F,
        vc: F2,
        force: F2,
        moment: F2,
        stuck: I,
        contact: I,
        pos: F2,
        quat: F2,
        lin_mom: F2,
        ang_mom: F2,
        size: F,
        speed2: F,
        nonfinite: I,
    ):
        v = wp.tid()
        r = robot[v]
        if running[r] == 0:
            return
        dt = fp[r, F_DT]
        if (flags[v] & FLAG_FIXED) != 0:
            for c in range(3):
                lin_mom[v, c] = S(0.0)
                ang_mom[v, c] = S(0.0)
        else:
            inv_m = vc[v, V_INV_MASS]
            inv_i = vc[v, V_INV_INERTIA]
            fx = force[v, 0]
            fy = force[v, 1]
            lin_mom[v, 2] = lin_mom[v, 2] + force[v, 2] * dt
            px = lin_mom[v, 0] + fx * dt
            py = lin_mom[v, 1] + fy * dt
            if contact[v] != 0:
                work = (fx * px + fy * py) * inv_m * dt
                if S(0.5) * inv_m * (px * px + py * py) + work <= S(0.0):
                    stuck[v] = 1
                if stuck[v] != 0:
                    px = S(0.0)
                    py = S(0.0)
            lin_mom[v, 0] = px
            lin_mom[v, 1] = py
            pz = lin_mom[v, 2]
            x = pos[v, 0] + px * inv_m * dt
            y = pos[v, 1] + py * inv_m * dt
            z = pos[v, 2] + pz * inv_m * dt
            pos[v, 0] = x
            pos[v, 1] = y
            pos[v, 2] = z
            wp.atomic_max(speed2, r, (px * px + py * py + pz * pz) * (inv_m * inv_m))
            lx = ang_mom[v, 0] + moment[v, 0] * dt
            ly = ang_mom[v, 1] + moment[v, 1] * dt
            lz = ang_mom[v, 2] + moment[v, 2] * dt
            ang_mom[v, 0] = lx
            ang_mom[v, 1] = ly
            ang_mom[v, 2] = lz
            dw, ddx, ddy, ddz = quat_from_rotvec(lx * inv_i * dt, ly * inv_i * dt, lz * inv_i * dt)
            qw, qx, qy, qz = qmul(dw, ddx, ddy, ddz, quat[v, 0], quat[v, 1], quat[v, 2], quat[v, 3])
            norm = S(1.0) / wp.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
            qw = qw * norm
            quat[v, 0] = qw
            quat[v, 1] = qx * norm
            quat[v, 2] = qy * norm
            quat[v, 3] = qz * norm
            bound = S(POSITION_BOUND)
            if not (
                wp.abs(x) < bound and wp.abs(y) < bound and wp.abs(z) < bound and wp.abs(qw) <= S(QUAT_BOUND)
            ):
                nonfinite[r] = 1
        size[v] = voxel_size(v, r, step[r] + 1, fp, ip, flags, cos_phase, sin_phase, phase, vc)

    # ------------------------------------------------------------ robots
    @wp.func
    def com_sample(r: int, row: int, t: S, voff: I, vc: F2, pos: F2, com_traj: F3):
        """``kernels.com``: the mass-weighted centre of robot r into com_traj[r, row]."""
        total = S(0.0)
        for v in range(voff[r], voff[r + 1]):
            total += vc[v, V_WEIGHT]
        com_traj[r, row, 0] = t
        for c in range(3):
            acc = S(0.0)
            for v in range(voff[r], voff[r + 1]):
                acc += vc[v, V_WEIGHT] * pos[v, c]
            com_traj[r, row, 1 + c] = acc / total

    @wp.kernel(module=module, enable_backward=False)
    def robots(
        after_step: int,
        running: I,
        step: I,
        fp: F2,
        ip: I2,
        voff: I,
        foff: I,
        vc: F2,
        pos: F2,
        bad: I,
        nonfinite: I,
        speed2: F,
        travel: F,
        status: I,
        done: I,
        n_com: I,
        com_traj: F3,
        frames: F2,
    ):
        """After a step (``after_step`` 1): the robot's status and collision travel, then the
        top of its next step as ``kernels.run_robot``; ``after_step`` 0: the top of step 0."""
        r = wp.tid()
        if running[r] == 0:
            return
        dt = fp[r, F_DT]
        k = step[r]
        if after_step != 0:
            code = STATUS_OK
            if bad[r] != 0:
                code = STATUS_STRAIN
            elif nonfinite[r] != 0:
                code = STATUS_NONFINITE
            if code != STATUS_OK:
                status[r] = code
                done[r] = k + 1
                com_sample(r, n_com[r], S(k + 1) * dt, voff, vc, pos, com_traj)
                n_com[r] = n_com[r] + 1
                running[r] = 0
                return
            margin = S(COLLIDE_MARGIN) * fp[r, F_L]
            tr = travel[r]
            if ip[r, I_COLLIDE] != 0 and S(2.0) * tr >= margin:
                tr = S(0.0)
            travel[r] = tr + wp.sqrt(wp.max(speed2[r], S(0.0))) * dt
            speed2[r] = S(0.0)
            k = k + 1
            step[r] = k
        every = ip[r, I_RECORD]
        n = voff[r + 1] - voff[r]
        if every > 0 and k % every == 0:
            row = foff[r] + (k // every) * n
            for v in range(n):
                for c in range(3):
                    frames[row + v, c] = pos[voff[r] + v, c]
        after = k - ip[r, I_SETTLE_STEPS]
        cap = com_traj.shape[1]
        if after >= 0 and after % ip[r, I_COM_EVERY] == 0 and n_com[r] < cap - 1:
            com_sample(r, n_com[r], S(k) * dt, voff, vc, pos, com_traj)
            n_com[r] = n_com[r] + 1
        if k == ip[r, I_STEPS]:
            done[r] = k
            com_sample(r, n_com[r], S(k) * dt, voff, vc, pos, com_traj)
            n_com[r] = n_com[r] + 1
            running[r] = 0

    return Kernels(S, links, forces, integrate, robots, actuate)
