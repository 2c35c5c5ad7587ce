"""A slow, obvious NumPy/SciPy version of the engine's step, to check the numba kernels.

Written from docs/physics.md directly, one link and one voxel at a time with SciPy rotations and
3x3 matrices, no series expansions and no fused arithmetic. Only for small test cases.

Materials per voxel: the reference takes each voxel's E_i and rho_i (``voxel_materials``) and
derives every constant itself, link by link and voxel by voxel: a link's modulus
2 E_a E_b / (E_a + E_b), its beam constants from that modulus, its bond damping
2 zeta sqrt(m_link / (E_link L)) with m_link the mean mass of its two voxels; each voxel's mass
rho_i L^3, inertia m L^2 / 6, floor stiffness 2 E_i L and damping 2 zeta sqrt(m_i E_i L).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from softevo.sim import system as S

# proper rotations taking the link's world axis onto +x (x: identity, y: -90 deg about z,
# z: +90 deg about y)
AXIS_TO_X = [np.eye(3), np.array([[0, 1, 0], [-1, 0, 0], [0, 0, 1]]),
             np.array([[0, 0, 1], [0, 1, 0], [-1, 0, 0]])]


def rot(q_wxyz: np.ndarray) -> Rotation:
    return Rotation.from_quat([q_wxyz[1], q_wxyz[2], q_wxyz[3], q_wxyz[0]])


def wxyz(r: Rotation) -> np.ndarray:
    x, y, z, w = r.as_quat()
    return np.array([w, x, y, z])


def voxel_materials(scene, batch):
    """(E, rho) of every simulated voxel of a one-robot batch, from the scene itself."""
    E = np.full(len(batch.flags), scene.material.youngs_modulus)
    rho = np.full(len(batch.flags), scene.material.density)
    idx = np.argwhere(S.largest_component(scene.body) > 0)
    if scene.youngs_modulus_field is not None:
        E = scene.youngs_modulus_field[tuple(idx.T)]
    if scene.density_field is not None:
        rho = scene.density_field[tuple(idx.T)]
    return E, rho


def link_forces(batch, pos, quat, size, small, prev, prev_valid, fp, mats, scene):
    """Forces and moments of every link (mutates small/prev/prev_valid like the kernel)."""
    n = len(pos)
    force, moment = np.zeros((n, 3)), np.zeros((n, 3))
    E_v, rho_v = mats
    L = fp[S.F_L]
    nu, zeta = scene.material.poisson_ratio, scene.material.damping_bond
    for l, (i, j, ax) in enumerate(zip(batch.link_neg, batch.link_pos, batch.link_axis, strict=True)):
        E = 2 * E_v[i] * E_v[j] / (E_v[i] + E_v[j])
        a1, a2, b1, b2, b3 = E * L, E * L**3 / (12 * (1 + nu)), E * L, E * L**2 / 2, E * L**3 / 6
        m_link = 0.5 * (rho_v[i] + rho_v[j]) * L**3
        damp = 2 * zeta * np.sqrt(m_link / (E * L)) * 0.5 / fp[S.F_DT]
        P = AXIS_TO_X[ax]
        Ri = rot(quat[i]).as_matrix()
        r = P @ Ri.T @ (pos[j] - pos[i])  # link frame, negative voxel's orientation
        rel = rot(quat[i]).inv() * rot(quat[j])
        rel_link = Rotation.from_matrix(P @ rel.as_matrix() @ P.T)
        rest = 0.5 * (size[i] + size[j])
        turn, extend = abs(r[1]) + abs(r[2]), abs(r[0] - rest)
        if small[l] and (turn > 0.05 * r[0] or extend > 0.5 * rest):
            small[l], prev_valid[l] = False, False
        elif not small[l] and turn < 0.05 / 1.2 * r[0] and extend < 0.5 / 1.2 * rest:
            small[l], prev_valid[l] = True, False
        if small[l]:
            align = Rotation.identity()
            d = r - [rest, 0, 0]
        else:
            u = r / np.linalg.norm(r)
            align, _ = Rotation.align_vectors([[1, 0, 0]], [u])  # takes u onto +x
            d = np.array([np.linalg.norm(r) - rest, 0, 0])
        t1 = align.as_rotvec() if not small[l] else np.zeros(3)
        t2 = (align * rel_link).as_rotvec()
        now = np.concatenate([d, t1, t2])
        e = now + (damp * (now - prev[:, l]) if prev_valid[l] else 0.0)
        prev[:, l], prev_valid[l] = now, True
        ed, e1, e2 = e[:3], e[3:6], e[6:]
        fa = np.array([a1 * ed[0] * rest / L, b1 * ed[1] - b2 * (e1[2] + e2[2]),
                       b1 * ed[2] + b2 * (e1[1] + e2[1])])
        ma = np.array([a2 * (e2[0] - e1[0]), -b2 * ed[2] - b3 * (2 * e1[1] + e2[1]),
                       b2 * ed[1] - b3 * (2 * e1[2] + e2[2])])
        mb = np.array([-a2 * (e2[0] - e1[0]), -b2 * ed[2] - b3 * (e1[1] + 2 * e2[1]),
                       b2 * ed[1] - b3 * (e1[2] + 2 * e2[2])])
        back = Ri @ P.T @ align.inv().as_matrix()
        force[i] += back @ fa
        force[j] -= back @ fa
        moment[i] += back @ ma
        moment[j] += back @ mb
    return force, moment


def step(batch, state, size, static, small, prev, prev_valid, fp, env, mats, scene):
    """One full step (links, world forces, semi-implicit Euler) without self-collisions."""
    pos, quat, lin, ang = state
    force, moment = link_forces(batch, pos, quat, size, small, prev, prev_valid, fp, mats, scene)
    dt, g, L = fp[S.F_DT], fp[S.F_GRAVITY], fp[S.F_L]
    zg, zc = scene.material.damping_global, scene.material.damping_collision
    for v in range(len(pos)):
        if batch.flags[v] & S.FLAG_FIXED:
            lin[v], ang[v] = 0.0, 0.0
            continue
        E, m = mats[0][v], mats[1][v] * L**3
        inertia = m * L**2 / 6
        vel = lin[v] / m
        f = force[v] + batch.ext_force[v] - 2 * zg * np.sqrt(m * E * L) * vel - [0, 0, m * g]
        mom = moment[v] - 2 * zg * np.sqrt(inertia * E * L**3) * ang[v] / inertia
        R = rot(quat[v]).as_matrix()
        if env == 1:  # water drag on exposed faces moving outward
            for a in range(3):
                for side, sign in ((0, -1.0), (1, 1.0)):
                    if batch.nbr[v, 2 * a + side] < 0:
                        normal = sign * R[:, a]
                        vn = vel @ normal
                        if vn > 0:
                            f -= fp[S.F_DRAG] * size[v] ** 2 * vn**2 * normal
        contact = False
        if env == 0:
            pen = 0.5 * size[v] - pos[v, 2]
            if pen >= 0:
                contact = True
                normal = 2 * E * L * pen
                f[2] += normal - 2 * zc * np.sqrt(m * E * L) * vel[2]
                if static[v] and f[0] ** 2 + f[1] ** 2 > (fp[S.F_MUS] * normal) ** 2:
                    static[v] = False
                elif not static[v]:
                    hv = np.hypot(vel[0], vel[1])
                    if hv > 1e-9 * fp[S.F_L] / dt:
                        f[:2] -= fp[S.F_MUK] * normal * vel[:2] / hv
            else:
                static[v] = False
        lin[v] += f * dt
        if contact:
            work = (f[0] * lin[v, 0] + f[1] * lin[v, 1]) / m * dt
            if 0.5 / m * (lin[v, 0] ** 2 + lin[v, 1] ** 2) + work <= 0:
                static[v] = True
            if static[v]:
                lin[v, :2] = 0.0
        pos[v] += lin[v] / m * dt
        ang[v] += mom * dt
        quat[v] = wxyz(Rotation.from_rotvec(ang[v] / inertia * dt) * rot(quat[v]))
