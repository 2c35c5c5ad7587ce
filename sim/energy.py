"""The energy audit: where an evaluation's energy comes from and where it goes.

``audit(scene)`` runs one scene step by step through the numba engine's own sub-steps
(``sim.kernels``: actuate, link forces, contacts, mesh drag, voxel update: the same calls, in
the same order, as ``kernels.step``, so the trajectory is the engine's) and, around every
step, evaluates the energies of the state and the work of every force from the model's
equations (docs/physics.md, "Energy"):

- mechanical energy: kinetic sum |p|^2 / 2m, rotational sum |H|^2 / 2I, gravitational
  sum m g z, elastic: each link's beam energy in the co-rotational frame the engine uses
  (``link_energy``), the floor's penalty springs k pen^2 / 2 and the self-contact springs
  k overlap^2 / 2;
- actuator work: what changing the sizes does at fixed positions: the elastic energy at the
  new sizes minus that at the old ones, each step (links, floor, contacts, from the nominal
  sizes the body is built at), plus its two shares of the step's own: the integrator's (the
  size change's work on S below) and the bond dampers' (they act on the elongation, so they
  answer a rest length's change: minus their axial force times that change);
- dissipation: the work of the global damping, the bond damping (the engine's link loads
  minus the elastic ones, less the dampers' actuator share), the floor's collision damping,
  friction (a voxel's change of kinetic energy less the work of every other force on it:
  kinetic friction and the static rule's zeroed momenta), drag and contact damping, each as
  F . v_mid dt with v_mid the mean of the velocities before and after the step (exactly
  what changes the kinetic energy in the semi-implicit Euler step);
- ``frame_switches``: the jumps of the elastic energy when links change co-rotational frame;
- ``link_nonconservative``: the work of the part of the links' loads that is not the
  gradient of their energy (the beam's moments balance its forces about the nominal arm L);
- the integrator's term S = dt/2 sum(F . v + M . omega) of the conservative loads: the
  semi-implicit Euler step keeps E + S (exactly for linear springs), so the mechanical
  energy itself can differ from its exact value by |S| at either end (the tolerance).

``Audit.summary()`` is the ``energy`` object of ``softevo simulate --json --energy``.
The cuda engine computes the same steps (the cross-engine tests hold it to 1e-9 of the
body); its runs are audited through the numba engine's steps, and ``engine_agreement`` says
how far the two runs' final positions are apart. The audit's own loads are float64 in
either precision (in "mixed" the engine's links are float32: their damping share then holds
float32's rounding).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numba import njit

from . import kernels, physics, system
from .cache import drop_foreign_entries, drop_stale_entries
from .physics import COLLIDE_MARGIN
from .result import prepare
from .scene import Scene

# the audit's cached code inlines the engine's sub-steps: dropped when any of their sources
# changes (``sim.cache``), as the engine's own are
_HERE = Path(__file__).parent
drop_foreign_entries(_HERE / "__pycache__", "energy")
SOURCES = ("energy.py", "kernels.py", "physics.py", "substeps.py", "system.py")
drop_stale_entries(_HERE / "__pycache__", [_HERE / name for name in SOURCES], "energy")

# the physics compiled as the CPU engine compiles it (same fma, same flags): the audit's link
# frames take the same decisions as the engine's
_phys = physics.compiled(njit(inline="always", fastmath=kernels.FASTMATH, error_model="numpy"),
                         kernels.fma)
link_geometry, link_frame, reframe = _phys.link_geometry, _phys.link_frame, _phys.reframe
frame_mode = _phys.frame_mode
link_loads, face_drag, voxel_world = _phys.link_loads, _phys.face_drag, _phys.voxel_world
opposite = kernels.opposite
JIT = dict(cache=True, error_model="numpy")

# columns of the audit's series, one row per step (row k: the state before step k, the
# works summed over steps 0 .. k-1)
COLUMNS = (
    "t", "kinetic", "rotational", "gravitational", "elastic_links", "elastic_floor",
    "elastic_contacts", "integrator_term", "actuator_links", "actuator_floor",
    "actuator_contacts", "actuator_integrator", "actuator_damping", "external", "global_damping",
    "bond_damping", "floor_damping", "friction", "drag", "contact_damping", "frame_switches",
    "link_nonconservative", "com_x", "com_y", "com_z",
)
(C_T, C_KIN, C_ROT, C_GRAV, C_ELINK, C_EFLOOR, C_ECONT, C_S, C_ALINK, C_AFLOOR, C_ACONT, C_AINT,
 C_ADAMP, C_EXT,
 C_DGLOB, C_DBOND, C_DFLOOR, C_DFRIC, C_DDRAG, C_DCONT, C_FRAMES, C_NONCONS, C_COMX, C_COMY,
 C_COMZ) = range(len(COLUMNS))
N_COLUMNS = len(COLUMNS)
DISSIPATION = ("global_damping", "bond_damping", "floor_damping", "friction", "drag",
               "contact_damping")
ELASTIC = ("elastic_links", "elastic_floor", "elastic_contacts")
MECHANICAL = [C_KIN, C_ROT, C_GRAV, C_ELINK, C_EFLOOR, C_ECONT]
ACTUATOR = ("actuator_links", "actuator_floor", "actuator_contacts", "actuator_integrator",
            "actuator_damping")


@njit(inline="always", **JIT)
def link_energy(k_axial, a2, b1, b2, b3, d, ey, ez, t1y, t1z, t2x, t2y, t2z):
    """Strain energy of one link's beam (docs/physics.md) for the deformation the engine's
    frame gives (elongation d, transverse offsets ey, ez, end rotations t1 = (0, t1y, t1z)
    and t2), constants already scaled by the link's stiffness; ``k_axial`` = a1 rest / L.
    Its derivatives are ``physics.beam``'s loads: the axial force k_axial d, the transverse
    b1 ey - b2 (t1z + t2z) and b1 ez + b2 (t1y + t2y), the moments."""
    return (0.5 * k_axial * d * d + 0.5 * a2 * t2x * t2x + 0.5 * b1 * (ey * ey + ez * ez)
            - b2 * ey * (t1z + t2z) + b2 * ez * (t1y + t2y)
            + b3 * (t1z * t1z + t1z * t2z + t2z * t2z + t1y * t1y + t1y * t2y + t2y * t2y))


@njit(inline="always", **JIT)
def frame_energy(k_axial, a2, b1, b2, b3, dd):
    """``link_energy`` of the deformation tuple ``physics.link_frame`` gives."""
    d, ey, ez, t1y, t1z, t2x, t2y, t2z = dd
    return link_energy(k_axial, a2, b1, b2, b3, d, ey, ez, t1y, t1z, t2x, t2y, t2z)


@njit(**JIT)
def link_pass(p, neg, pos_, axis, stiff, damping, pos, quat, size, old_size, mode, force, moment,
              dforce, previous, damper, torque, extra):
    """Every link's elastic energy in the frame the engine puts it in (``mode``: 0 before the
    first step, +1 small-angle, -1 large, updated here with the engine's hysteresis), its
    undamped loads summed into ``force``/``moment`` (overwritten), the actuator work of the
    size change from ``old_size`` (at these positions) and the
    energy jumps of links that change frame; ``dforce`` (overwritten) gets the change of each
    voxel's load that the size change made (the axial force's), for the integrator's term.
    ``previous`` (per link) holds the elongation the engine damps against, ``damper`` the
    axial force of the bond damping (``damping``: gamma / (2 dt) per link; none on a link's
    first step in a frame), both updated here: the actuator works through the damper too,
    -damper times the rest length's change since the last step (the change that the
    damper's force answers). ``torque`` and ``extra`` (overwritten) get the part of the
    elastic loads that is not the gradient of the beam's energy: in the small-angle frame
    the net torque of a link's loads about its negative voxel (the loads of an energy that
    does not change when the pair turns as a whole have none; the beam's moment on the
    negative end takes the arm L where the ends are r apart), on that voxel; in the large
    one the transverse forces' excess over the energy's (which are L / length of them).
    Returns (energy, actuator work, jumps, the actuator's work through the dampers)."""
    force[:] = 0.0
    moment[:] = 0.0
    dforce[:] = 0.0
    torque[:] = 0.0
    extra[:] = 0.0
    energy = work = jumps = through = 0.0
    L = p.L
    for j in range(len(neg)):
        a, b, ax, s = neg[j], pos_[j], axis[j], stiff[j]
        rest = 0.5 * (size[a] + size[b])
        was = mode[j]
        R, rx, ry, rz, ow, ox, oy, oz = link_geometry(
            quat[a, 0], quat[a, 1], quat[a, 2], quat[a, 3], quat[b, 0], quat[b, 1], quat[b, 2],
            quat[b, 3], pos[b, 0] - pos[a, 0], pos[b, 1] - pos[a, 1], pos[b, 2] - pos[a, 2], ax)
        k_ax, a2, b1, b2, b3 = p.a1 * s * rest / L, p.a2 * s, p.b1 * s, p.b2 * s, p.b3 * s
        small = mode[j] >= 0.0
        W, dd, change = link_frame(small, R, ax, rx, ry, rz, ow, ox, oy, oz, rest)
        mode[j] = frame_mode(small)
        if change:  # the engine's hysteresis: computed again in the other frame, flipped
            before = frame_energy(k_ax, a2, b1, b2, b3, dd)
            W, dd, _, mode[j] = reframe(small, R, ax, rx, ry, rz, ow, ox, oy, oz, rest)
            jumps += frame_energy(k_ax, a2, b1, b2, b3, dd) - before
        d, ey, ez, t1y, t1z, t2x, t2y, t2z = dd
        damp = damping[j] if was != 0.0 and was == mode[j] else 0.0
        damper[j] = k_ax * damp * (d - previous[j])
        previous[j] = d
        # the rest length's change this step is what the damper's force answers
        through -= damper[j] * (rest - 0.5 * (old_size[a] + old_size[b]))
        u = link_energy(k_ax, a2, b1, b2, b3, d, ey, ez, t1y, t1z, t2x, t2y, t2z)
        energy += u
        # the same geometry at the previous sizes: d grows by the rest's change
        old_rest = 0.5 * (old_size[a] + old_size[b])
        d_old = d + rest - old_rest
        work += u - link_energy(p.a1 * s * old_rest / L, a2, b1, b2, b3, d_old, ey, ez,
                                t1y, t1z, t2x, t2y, t2z)
        # the axial force's change, along the beam's x axis in world axes (W's column 0)
        df = p.a1 * s / L * (rest * d - old_rest * d_old)
        opposite(dforce, a, b, df * W[0], df * W[3], df * W[6])
        fx, fy, fz, max_, may, maz, mbx, mby, mbz = link_loads(
            W, s, rest, L, p.a1, p.a2, p.b1, p.b2, p.b3, d, ey, ez, t1y, t1z, t2x, t2y, t2z)
        opposite(force, a, b, fx, fy, fz)
        moment[a, 0] += max_
        moment[a, 1] += may
        moment[a, 2] += maz
        moment[b, 0] += mbx
        moment[b, 1] += mby
        moment[b, 2] += mbz
        if mode[j] > 0.0:  # the moment on the negative end is not its potential's
            wx, wy, wz = pos[b, 0] - pos[a, 0], pos[b, 1] - pos[a, 1], pos[b, 2] - pos[a, 2]
            torque[a, 0] += max_ + mbx - (wy * fz - wz * fy)  # + w x (-f), the force on b
            torque[a, 1] += may + mby - (wz * fx - wx * fz)
            torque[a, 2] += maz + mbz - (wx * fy - wy * fx)
        else:  # the transverse forces are the potential's times L / length
            bend = p.b2 * s * (1.0 - L / math.sqrt(rx * rx + ry * ry + rz * rz))
            gy, gz = -bend * (t1z + t2z), bend * (t1y + t2y)  # on the negative end
            extra[a, 0] += W[1] * gy + W[2] * gz
            extra[a, 1] += W[4] * gy + W[5] * gz
            extra[a, 2] += W[7] * gy + W[8] * gz
            extra[b, 0] -= W[1] * gy + W[2] * gz
            extra[b, 1] -= W[4] * gy + W[5] * gz
            extra[b, 2] -= W[7] * gy + W[8] * gz
    return energy, work, jumps, through


@njit(**JIT)
def contact_pass(p, count, pairs, pos, size, old_size, vconst, force, dforce):
    """The self-contact springs of the touching candidate pairs: their energy
    k overlap^2 / 2 (``physics.contact_push``'s stiffness), their spring forces k overlap
    along the line of centres into ``force`` (overwritten), and the actuator work of the
    size change from ``old_size`` at these positions, its change of the spring forces added
    to ``dforce``. Returns (energy, actuator work)."""
    force[:] = 0.0
    energy = work = 0.0
    reach = p.contact_reach
    for q in range(count):
        i, j = pairs[q, 0], pairs[q, 1]
        dx, dy, dz = pos[j, 0] - pos[i, 0], pos[j, 1] - pos[i, 1], pos[j, 2] - pos[i, 2]
        dist = math.sqrt(dx * dx + dy * dy + dz * dz)
        ki, kj = vconst[i, system.V_KFLOOR], vconst[j, system.V_KFLOOR]
        k = p.contact_stiff * (ki if ki == kj else 2.0 * ki * kj / (ki + kj))
        overlap = reach * (size[i] + size[j]) - dist
        before = f_old = 0.0
        old = reach * (old_size[i] + old_size[j]) - dist
        if old > 0.0 and dist > 0.0:
            before, f_old = 0.5 * k * old * old, k * old / dist
        if overlap > 0.0 and dist > 0.0:
            u = 0.5 * k * overlap * overlap
            f = k * overlap / dist
            opposite(force, j, i, f * dx, f * dy, f * dz)
        else:
            u = f = 0.0
        energy += u
        work += u - before
        df = f - f_old
        opposite(dforce, j, i, df * dx, df * dy, df * dz)
    return energy, work


@njit(**JIT)
def state_row(p, flags, vconst, pos, lin_mom, ang_mom, size, old_size, f_links, m_links,
              f_contacts, dforce, row):
    """The state's energies into ``row`` (kinetic, rotational, gravitational, floor springs,
    the integrator's term S of the conservative loads ``f_links``/``m_links``/``f_contacts``
    plus gravity and the floor, the centre of mass). Returns the floor's actuator work and
    the change of S that the size change made (``dforce``, the links' and contacts' share,
    plus the floor's)."""
    land = p.env == system.ENV_LAND
    kin = rot = grav = floor = power = work = dpower = 0.0
    total = cx = cy = cz = 0.0
    for v in range(len(flags)):
        m, inv_m = vconst[v, system.V_MASS], vconst[v, system.V_INV_MASS]
        inv_i = vconst[v, system.V_INV_INERTIA]
        w = vconst[v, system.V_WEIGHT]
        total += w
        cx += w * pos[v, 0]
        cy += w * pos[v, 1]
        cz += w * pos[v, 2]
        grav += m * p.gravity * pos[v, 2]
        if flags[v] & system.FLAG_FIXED:
            continue
        px, py, pz = lin_mom[v, 0], lin_mom[v, 1], lin_mom[v, 2]
        lx, ly, lz = ang_mom[v, 0], ang_mom[v, 1], ang_mom[v, 2]
        kin += 0.5 * inv_m * (px * px + py * py + pz * pz)
        rot += 0.5 * inv_i * (lx * lx + ly * ly + lz * lz)
        fz = f_links[v, 2] + f_contacts[v, 2] - m * p.gravity
        if land:
            pen = 0.5 * size[v] - pos[v, 2]
            if pen >= 0.0:
                floor += 0.5 * vconst[v, system.V_KFLOOR] * pen * pen
                fz += vconst[v, system.V_KFLOOR] * pen
            old = 0.5 * old_size[v] - pos[v, 2]
            work += (0.5 * vconst[v, system.V_KFLOOR] * (max(pen, 0.0) ** 2 - max(old, 0.0) ** 2))
            dpower += inv_m * vconst[v, system.V_KFLOOR] * (max(pen, 0.0) - max(old, 0.0)) * pz
        dpower += inv_m * (dforce[v, 0] * px + dforce[v, 1] * py + dforce[v, 2] * pz)
        power += inv_m * ((f_links[v, 0] + f_contacts[v, 0]) * px
                          + (f_links[v, 1] + f_contacts[v, 1]) * py + fz * pz)
        power += inv_i * (m_links[v, 0] * lx + m_links[v, 1] * ly + m_links[v, 2] * lz)
    row[C_KIN], row[C_ROT], row[C_GRAV], row[C_EFLOOR] = kin, rot, grav, floor
    row[C_S] = 0.5 * p.dt * power
    row[C_COMX], row[C_COMY], row[C_COMZ] = cx / total, cy / total, cz / total
    return work, 0.5 * p.dt * dpower


@njit(**JIT)
def step_works(p, flags, ext_force, nbr, vconst, pos0, quat0, mom0, ang0, lin_mom, ang_mom, size,
               f_engine, m_engine, f_links, m_links, f_with_contacts, f_spring, f_with_drag,
               torque, extra, row):
    """The work of each force over one step into ``row`` (added to it): the state before the
    step (``pos0``, ``quat0``, ``mom0``, ``ang0``), the momenta after it, the engine's link
    loads (``f_engine``/``m_engine``), the elastic ones (``f_links``/``m_links``), the
    engine's force once the contacts were added (``f_with_contacts``) and once the mesh drag
    was (``f_with_drag``), the contact springs (``f_spring``), the links' non-gradient loads
    (``torque``, ``extra``: ``link_pass``). Each as F . v_mid dt (M . omega_mid dt), v_mid
    the mean of the velocities before and after the step."""
    world = voxel_world(p)
    dt, g, drag, water, land = world[0], world[1], world[2], world[3], world[4]
    for v in range(len(flags)):
        if flags[v] & system.FLAG_FIXED:
            continue
        m, inv_m = vconst[v, system.V_MASS], vconst[v, system.V_INV_MASS]
        inv_i = vconst[v, system.V_INV_INERTIA]
        v0x, v0y, v0z = mom0[v, 0] * inv_m, mom0[v, 1] * inv_m, mom0[v, 2] * inv_m
        # v_mid dt and omega_mid dt: what a force's and a moment's work is taken over
        vmx = 0.5 * (mom0[v, 0] + lin_mom[v, 0]) * inv_m * dt
        vmy = 0.5 * (mom0[v, 1] + lin_mom[v, 1]) * inv_m * dt
        vmz = 0.5 * (mom0[v, 2] + lin_mom[v, 2]) * inv_m * dt
        w0x, w0y, w0z = ang0[v, 0] * inv_i, ang0[v, 1] * inv_i, ang0[v, 2] * inv_i
        wmx = 0.5 * (ang0[v, 0] + ang_mom[v, 0]) * inv_i * dt
        wmy = 0.5 * (ang0[v, 1] + ang_mom[v, 1]) * inv_i * dt
        wmz = 0.5 * (ang0[v, 2] + ang_mom[v, 2]) * inv_i * dt
        # the engine's force on v, term by term
        blx, bly, blz = f_engine[v, 0] - f_links[v, 0], f_engine[v, 1] - f_links[v, 1], \
            f_engine[v, 2] - f_links[v, 2]
        row[C_NONCONS] += (torque[v, 0] * wmx + torque[v, 1] * wmy + torque[v, 2] * wmz
                          + extra[v, 0] * vmx + extra[v, 1] * vmy + extra[v, 2] * vmz)
        row[C_DBOND] += (blx * vmx + bly * vmy + blz * vmz
                         + (m_engine[v, 0] - m_links[v, 0]) * wmx
                         + (m_engine[v, 1] - m_links[v, 1]) * wmy
                         + (m_engine[v, 2] - m_links[v, 2]) * wmz)
        cx = f_with_contacts[v, 0] - f_engine[v, 0]
        cy = f_with_contacts[v, 1] - f_engine[v, 1]
        cz = f_with_contacts[v, 2] - f_engine[v, 2]
        row[C_DCONT] += ((cx - f_spring[v, 0]) * vmx + (cy - f_spring[v, 1]) * vmy
                         + (cz - f_spring[v, 2]) * vmz)
        # drag: the mesh's (added by the engine before the voxel update) and the faces'
        dx = f_with_drag[v, 0] - f_with_contacts[v, 0]
        dy = f_with_drag[v, 1] - f_with_contacts[v, 1]
        dz = f_with_drag[v, 2] - f_with_contacts[v, 2]
        if water:
            exposed = 0
            for f in range(6):
                exposed |= (1 if nbr[v, f] < 0 else 0) << f
            dx, dy, dz = face_drag(dx, dy, dz, drag, exposed, quat0[v, 0], quat0[v, 1],
                                   quat0[v, 2], quat0[v, 3], v0x, v0y, v0z, size[v] * size[v])
        row[C_DDRAG] += dx * vmx + dy * vmy + dz * vmz
        ex, ey, ez = ext_force[v, 0], ext_force[v, 1], ext_force[v, 2]
        row[C_EXT] += ex * vmx + ey * vmy + ez * vmz
        c_lin, c_ang = vconst[v, system.V_CGLIN], vconst[v, system.V_CGANG]
        row[C_DGLOB] -= (c_lin * (v0x * vmx + v0y * vmy + v0z * vmz)
                         + c_ang * (w0x * wmx + w0y * wmy + w0z * wmz))
        # every force the model names: links (damped), contacts, drag, external, global
        # damping, gravity, the floor; what else changed the kinetic energy is friction's
        fx = f_with_contacts[v, 0] + dx + ex - c_lin * v0x
        fy = f_with_contacts[v, 1] + dy + ey - c_lin * v0y
        fz = f_with_contacts[v, 2] + dz + ez - c_lin * v0z - m * g
        if land:
            pen = 0.5 * size[v] - pos0[v, 2]
            if pen >= 0.0:
                damping = -vconst[v, system.V_CCOLL] * v0z
                row[C_DFLOOR] += damping * vmz
                fz += vconst[v, system.V_KFLOOR] * pen + damping
        p1x, p1y, p1z = lin_mom[v, 0], lin_mom[v, 1], lin_mom[v, 2]
        p0x, p0y, p0z = mom0[v, 0], mom0[v, 1], mom0[v, 2]
        change = 0.5 * inv_m * ((p1x * p1x + p1y * p1y + p1z * p1z)
                                - (p0x * p0x + p0y * p0y + p0z * p0z))
        row[C_DFRIC] += change - (fx * vmx + fy * vmy + fz * vmz)


@njit(**JIT)
def audit_run(batch, state, real, series):
    """Run robot 0 of ``batch`` (alone) as ``kernels.run_robot`` does, filling ``series``
    (steps + 1 rows, ``COLUMNS``) step by step. Returns (status, steps done, the final
    positions)."""
    p, voxels, links, body = kernels.take_robot(batch, state, 0)
    n, m = len(voxels.flags), len(links.neg)
    work = kernels.robot_work(n, links, batch.poff[1] - batch.poff[0], voxels.surface, voxels.near,
                              p.collide, len(voxels.mesh_vert), real)
    contacts = kernels.Contacts(0, COLLIDE_MARGIN * p.L)
    mode = np.zeros(m)
    old_size = np.full(n, p.L)  # the body is built at the nominal size
    f_links, m_links = np.zeros((n, 3)), np.zeros((n, 3))
    f_spring, dforce = np.zeros((n, 3)), np.zeros((n, 3))
    previous, damper = np.zeros(m), np.zeros(m)
    torque, extra = np.zeros((n, 3)), np.zeros((n, 3))
    f_engine, m_engine = np.zeros((n, 3)), np.zeros((n, 3))
    f_with_contacts, f_with_drag = np.zeros((n, 3)), np.zeros((n, 3))
    pos0, quat0 = np.zeros((n, 3)), np.zeros((n, 4))
    mom0, ang0 = np.zeros((n, 3)), np.zeros((n, 3))
    code, done = system.STATUS_OK, p.steps
    bad, speed2 = 0, 0.0
    for k in range(p.steps + 1):
        row = series[k]  # its works hold steps 0 .. k-1 (the previous step copied them)
        row[C_T] = k * p.dt
        kernels.actuate((k - p.act_start) * p.dt, p, voxels, work)
        if k < p.steps:  # the engine's step (``kernels.step``), sub-step by sub-step
            bad = kernels.link_forces(p, links, body, work)
            f_engine[:], m_engine[:] = work.force.T, work.moment.T  # (3, n): rows by component
            contacts = kernels.contact_list(p, voxels, body, work, contacts)
            kernels.contact_forces(p, voxels, body, work, contacts)
            f_with_contacts[:] = work.force.T
            kernels.mesh_vertices(p, voxels, body, work)
            kernels.mesh_drag(p, voxels, body, work)
            f_with_drag[:] = work.force.T
        # the energies of the state before the step, and the actuator's work since the last
        pos, quat = body.pos.T, body.quat.T  # (n, 3), (n, 4) views of the engine's rows
        e_links, a_links, jumps, a_damp = link_pass(
            p, links.neg, links.pos, links.axis, links.stiff, links.damp, pos, quat,
            work.size, old_size, mode, f_links, m_links, dforce, previous, damper, torque, extra)
        e_cont, a_cont = contact_pass(p, max(contacts.count, 0), work.pairs, pos,
                                      work.size, old_size, voxels.vconst, f_spring, dforce)
        a_floor, a_int = state_row(p, voxels.flags, voxels.vconst, pos, body.lin_mom.T,
                                   body.ang_mom.T, work.size, old_size, f_links, m_links,
                                   f_spring, dforce, row)
        row[C_ELINK], row[C_ECONT] = e_links, e_cont
        row[C_ALINK] += a_links
        row[C_AFLOOR] += a_floor
        row[C_ACONT] += a_cont
        row[C_AINT] += a_int
        row[C_ADAMP] += a_damp
        row[C_FRAMES] += jumps
        old_size[:] = work.size
        if k == p.steps:
            break
        pos0[:], quat0[:] = body.pos.T, body.quat.T
        mom0[:], ang0[:] = body.lin_mom.T, body.ang_mom.T
        speed2 = kernels.voxel_update(p, voxels, body, work)
        contacts = kernels.Contacts(contacts.count, kernels.travel_after(contacts.travel, speed2, p.dt))
        nxt = series[k + 1]
        nxt[C_ALINK:] = row[C_ALINK:]
        step_works(p, voxels.flags, voxels.ext_force.T, voxels.nbr, voxels.vconst, pos0, quat0,
                   mom0, ang0, body.lin_mom.T, body.ang_mom.T, work.size, f_engine, m_engine,
                   f_links, m_links, f_with_contacts, f_spring, f_with_drag, torque, extra,
                   nxt)
        if bad or speed2 < 0.0 or contacts.count < 0:
            code = (system.STATUS_STRAIN if bad else system.STATUS_NONFINITE if speed2 < 0.0
                    else system.STATUS_CONTACTS)
            done = k + 1
            break
    return code, done, np.ascontiguousarray(body.pos.T)


@dataclass
class Audit:
    """One evaluation's energy audit: ``series`` (one row per step, ``COLUMNS``: the state's
    energies and the works summed so far, joules), the step ``dt``, whether the run ended
    stable and the engine that was audited."""

    series: np.ndarray
    dt: float
    stable: bool
    engine: str = "numba"
    final_positions: np.ndarray | None = None  # (n, 3) metres, the audited run's
    agreement: float | None = None  # largest distance from the engine's own final positions, m

    def column(self, name: str) -> np.ndarray:
        """The series' column ``name`` (one of ``COLUMNS``)."""
        return self.series[:, COLUMNS.index(name)]

    def start(self) -> np.ndarray:
        """The first row as it was before the first step's sizes were set (the body is built
        at the nominal size): its energies less the work of that size change."""
        row = self.series[0].copy()
        for energy, work in ((C_ELINK, C_ALINK), (C_EFLOOR, C_AFLOOR), (C_ECONT, C_ACONT),
                             (C_S, C_AINT)):
            row[energy] -= row[work]
        row[C_ALINK:C_COMX] = 0.0
        return row

    def mechanical(self) -> np.ndarray:
        """Kinetic + rotational + gravitational + elastic energy at every step, joules."""
        return self.series[:, MECHANICAL].sum(axis=1)

    def gain(self) -> np.ndarray:
        """The mechanical energy's change from the start (``start``) to every step."""
        return self.mechanical() - self.start()[MECHANICAL].sum()

    def actuator_work(self) -> np.ndarray:
        """The actuators' work up to every step (links, floor, contacts, the integrator's
        term and the dampers), joules."""
        return self.series[:, [C_ALINK, C_AFLOOR, C_ACONT, C_AINT, C_ADAMP]].sum(axis=1)

    def dissipated(self) -> np.ndarray:
        """The energy the dissipative forces removed up to every step (positive: removed;
        the bond dampers' share of the actuator's work is not dissipation)."""
        s = self.series
        return s[:, C_ADAMP] - s[:, [C_DGLOB, C_DBOND, C_DFLOOR, C_DFRIC, C_DDRAG, C_DCONT]].sum(axis=1)

    def excess(self) -> np.ndarray:
        """By how much the mechanical energy's gain exceeds the work put in (actuators and
        external forces) at every step, less the integrator's bound |S_start| + |S_k|:
        positive only where energy came from nowhere beyond what the step size explains."""
        s = self.series
        put_in = self.actuator_work() + s[:, C_EXT]
        return self.gain() - put_in - (abs(self.start()[C_S]) + np.abs(s[:, C_S]))

    def summary(self) -> dict:
        """The ``energy`` object of ``softevo simulate --json --energy`` (joules; changes from
        the start to the last step; ``dissipated``: energy removed, positive)."""
        s = self.series
        first, last = self.start(), s[-1]
        change = {name: float(last[COLUMNS.index(name)] - first[COLUMNS.index(name)])
                  for name in ("kinetic", "rotational", "gravitational", *ELASTIC)}
        mechanical = float(self.gain()[-1])
        actuator = float(self.actuator_work()[-1])
        dissipated = {name: -float(last[COLUMNS.index(name)]) for name in DISSIPATION}
        dissipated["bond_damping"] += float(last[C_ADAMP])  # the actuator's share is work
        known = sum(dissipated.values())
        external = float(last[C_EXT])
        excess = self.excess()
        return {
            "engine": self.engine,
            "steps": len(s) - 1,
            "dt": self.dt,
            "actuator_work": actuator,
            "actuator_work_parts": {"links": float(last[C_ALINK]), "floor": float(last[C_AFLOOR]),
                                    "contacts": float(last[C_ACONT]),
                                    "integrator": float(last[C_AINT]),
                                    "damping": float(last[C_ADAMP])},
            "external_work": external,
            "mechanical_change": mechanical,
            "mechanical_change_parts": change,
            "dissipated": dissipated,
            "dissipated_known": known,
            "unaccounted": actuator + external - mechanical - known,
            "frame_switches": float(last[C_FRAMES]),
            "link_nonconservative": float(last[C_NONCONS]),
            "integrator_term": float(last[C_S] - first[C_S]),
            "tolerance": float(abs(first[C_S]) + abs(last[C_S])),
            "peak_excess": float(excess.max()),
            "peak_excess_time": float(s[int(np.argmax(excess)), C_T]),
            "engine_agreement": self.agreement,
        }


def audit(scene: dict | Scene, engine: str = "numba",
          final_positions: np.ndarray | None = None) -> Audit:
    """The energy audit of one scene (a dict as docs/spec.md section 1, or a parsed
    ``Scene``) through the numba engine's steps; ``engine`` names the engine whose
    evaluation it stands for (``numba`` or ``cuda``: the same steps), and
    ``final_positions``, that engine's own (``Result.final_positions``), are compared with
    the audited run's (``Audit.agreement``). A scene refused unrun (``sim.result.prepare``:
    its step budget) gives an empty audit."""
    from .numba_engine import REALS

    parsed, robots, results, runnable = prepare([scene])
    robot = robots[0]
    dt = float(robot.fparams[system.F_DT])
    if not runnable:
        return Audit(np.zeros((1, N_COLUMNS)), dt, False, engine, np.zeros((0, 3)))
    batch, state = system.pack([robot])
    steps = int(robot.iparams[system.I_STEPS])
    series = np.zeros((steps + 1, N_COLUMNS))
    code, done, final = audit_run(batch, state, REALS[parsed[0].options.precision], series)
    stable = code == system.STATUS_OK
    agreement = None
    if final_positions is not None and np.shape(final_positions) == final.shape:
        agreement = float(np.max(np.linalg.norm(final - np.asarray(final_positions), axis=1),
                                 initial=0.0))
    return Audit(series[: done + 1] if stable else series[:done], dt, stable, engine, final,
                 agreement)
