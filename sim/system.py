"""Static model of one or many robots: the lattice, beam constants and per-robot parameters.

``build_robot(scene)`` turns a validated Scene into plain arrays for one robot;
``pack(robots)`` concatenates many robots into one ``Batch`` (struct of arrays with offsets)
that a single compiled kernel call steps in parallel. Per-robot constants travel packed as
rows of ``fparams``/``iparams`` (columns ``F_*``/``I_*``); the kernels read them as one
``Params`` named tuple per robot, built from its two rows in the same order.

Conventions (all SI):
- voxels are numbered in x-major order of the body over the largest face-connected component;
- ``pos``: (n, 3) float64 metres, voxel (i, j, k) starts at ((i + .5) L, (j + .5) L, (k + .5) L);
- ``quat``: (n, 4) float64 (w, x, y, z), identity at start;
- links join face neighbours; ``link_neg``/``link_pos`` are the voxels on the negative and
  positive side along ``link_axis`` (0 x, 1 y, 2 z).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from scipy import ndimage

from .scene import Scene

# Columns of the per-robot float parameter table ``fparams``.
F_L, F_A1, F_A2, F_B1, F_B2, F_B3, F_DT, F_GRAVITY, F_MUS, F_MUK = range(10)
F_DRAG, F_OMEGA, F_AMP, F_SETTLE = range(10, 14)
N_FPARAMS = 14
# Columns of the per-robot integer parameter table ``iparams``.
I_STEPS, I_SETTLE_STEPS, I_ENV, I_WAVE, I_RECORD, I_COLLIDE, I_COM_EVERY, I_N_FRAMES = range(8)
I_FREQ_FIELD = 8
N_IPARAMS = 9
# Columns of the per-voxel constant table ``vconst`` (one row per voxel).
V_MASS, V_INV_MASS, V_INV_INERTIA, V_KFLOOR, V_CCOLL, V_CGLIN, V_CGANG, V_OMEGA = range(8)
V_WEIGHT = 8
N_VCONST = 9

ENV_LAND, ENV_WATER, ENV_VOID = 0, 1, 2
ENV_CODES = {"land": ENV_LAND, "water": ENV_WATER, "void": ENV_VOID}
WAVE_CODES = {"sine": 0, "square": 1, "impulse": 2}
STEPS_PER_CYCLE = 2000  # the step also resolves the actuation cycle at least this finely
COM_SAMPLES = 200  # centre-of-mass samples kept per run (plus the start)
FLAG_FIXED, FLAG_ACTIVE = 1, 2


def largest_component(body: np.ndarray) -> np.ndarray:
    """Keep only the largest face-connected component of full voxels (ties: lowest label)."""
    labels, n = ndimage.label(body > 0)  # default structure: face connectivity
    if n <= 1:
        return body.copy()
    sizes = np.bincount(labels.ravel())[1:]
    keep = 1 + int(np.argmax(sizes))
    return np.where(labels == keep, body, 0).astype(body.dtype)


def stable_dt(voxel_size: float, density: float, youngs_modulus: float, fraction: float) -> float:
    """Step size: ``fraction`` of 1 / (2 pi f_link), f_link the axial frequency of one link."""
    return fraction * voxel_size * math.sqrt(density / youngs_modulus) / (2.0 * math.pi)


class Params(NamedTuple):
    """One robot's constants as the kernels read them: the ``fparams`` row, then the
    ``iparams`` row, field for column (SI units). The beam constants are those of the
    robot's reference modulus E_ref (the stiffest voxel's); each link scales them by its
    ``link_stiff`` = E_link / E_ref. Per-voxel constants (mass, damping, floor stiffness,
    actuation frequency) are rows of ``vconst``."""

    L: float  # voxel size, m
    a1: float  # axial stiffness E_ref L, N/m
    a2: float  # torsional stiffness E_ref L^3 / (12 (1 + nu)), N m
    b1: float  # shear stiffness E_ref L, N/m
    b2: float  # bend-shear coupling E_ref L^2 / 2, N
    b3: float  # bending stiffness E_ref L^3 / 6, N m
    dt: float  # step, s
    gravity: float  # m/s^2, along -z
    mu_s: float  # static friction coefficient
    mu_k: float  # kinetic friction coefficient
    drag: float  # water: 0.5 rho_fluid C_d, kg/m^3 (0 elsewhere)
    omega: float  # actuation angular frequency, rad/s (when every active voxel shares one)
    amp: float  # actuation amplitude (linear strain)
    settle: float  # settling time before actuation starts, s
    steps: int  # total steps, settling included
    settle_steps: int
    env: int  # ENV_LAND, ENV_WATER or ENV_VOID
    wave: int  # WAVE_CODES
    record: int  # record a frame every this many steps (0: none)
    collide: int  # 1: self-collisions on
    com_every: int  # a centre-of-mass sample every this many steps after settling
    n_frames: int  # frames recorded over the whole run
    freq_field: int  # 1: active voxels have frequencies of their own (``vconst[:, V_OMEGA]``)


class Robot(NamedTuple):
    """Arrays of one robot before packing."""

    voxels: np.ndarray  # (n, 3) int64 lattice indices
    pos: np.ndarray  # (n, 3) metres
    flags: np.ndarray  # (n,) int8: FLAG_FIXED | FLAG_ACTIVE
    phase: np.ndarray  # (n,) radians
    ext_force: np.ndarray  # (n, 3) newtons
    lin_mom: np.ndarray  # (n, 3) kg m / s
    ang_mom: np.ndarray  # (n, 3) kg m^2 / s
    nbr: np.ndarray  # (n, 6) int64 neighbour index for -x,+x,-y,+y,-z,+z (-1: exposed face)
    link_neg: np.ndarray  # (m,) int64
    link_pos: np.ndarray  # (m,) int64
    link_axis: np.ndarray  # (m,) int64
    vlink: np.ndarray  # (n, 6) int64 link on each face, ordered as nbr (m, the link count: none)
    surface: np.ndarray  # (s,) int64 voxels with at least one exposed face
    vconst: np.ndarray  # (n, N_VCONST) per-voxel constants
    link_stiff: np.ndarray  # (m,) E_link / E_ref
    link_damp: np.ndarray  # (m,) bond damping gamma_link / (2 dt)
    fparams: np.ndarray  # (N_FPARAMS,)
    iparams: np.ndarray  # (N_IPARAMS,)
    removed: int  # voxels dropped as not connected to the largest component


class Batch(NamedTuple):
    """Many robots concatenated; robot r owns voxels voff[r]:voff[r+1] and so on. Index
    arrays (nbr, link_neg, link_pos, vlink, surface) stay local to their robot: each robot's
    run takes its own slices."""

    voff: np.ndarray  # (R + 1,) int64
    loff: np.ndarray  # (R + 1,) int64
    soff: np.ndarray  # (R + 1,) int64 into ``surface``
    poff: np.ndarray  # (R + 1,) int64 into the collision pair buffer
    flags: np.ndarray
    cos_phase: np.ndarray
    sin_phase: np.ndarray
    phase: np.ndarray
    ext_force: np.ndarray
    nbr: np.ndarray  # voxel indices within the robot (-1: exposed face)
    link_neg: np.ndarray  # voxel indices within the robot
    link_pos: np.ndarray
    link_axis: np.ndarray
    vlink: np.ndarray  # link indices within the robot (its link count m: no link on that face)
    surface: np.ndarray  # voxel indices within the robot
    vconst: np.ndarray  # (N, N_VCONST)
    link_stiff: np.ndarray  # (M,)
    link_damp: np.ndarray  # (M,)
    fparams: np.ndarray  # (R, N_FPARAMS)
    iparams: np.ndarray  # (R, N_IPARAMS)


class State(NamedTuple):
    """Dynamic state of a batch (updated in place by the kernel)."""

    pos: np.ndarray  # (N, 3)
    quat: np.ndarray  # (N, 4)
    lin_mom: np.ndarray  # (N, 3)
    ang_mom: np.ndarray  # (N, 3)


def _lattice(body: np.ndarray):
    idx = np.argwhere(body > 0)  # x-major order
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
    vlink = np.full((len(idx), 6), len(link_neg), dtype=np.int64)  # m: no link on that face
    vlink[link_neg, 2 * link_axis + 1] = np.arange(len(link_neg))
    vlink[link_pos, 2 * link_axis] = np.arange(len(link_neg))
    return idx, lookup, nbr, link_neg, link_pos, link_axis, vlink


def series_modulus(e1: np.ndarray, e2: np.ndarray) -> np.ndarray:
    """Young's modulus of a link whose halves (length L/2 each) have moduli e1 and e2, springs
    in series: 2 e1 e2 / (e1 + e2); exactly e1 where e1 == e2."""
    return np.where(e1 == e2, e1, 2.0 * e1 * e2 / (e1 + e2))


def voxel_values(scene: Scene, body: np.ndarray, idx: np.ndarray):
    """Young's modulus (Pa), density (kg/m^3) and actuation frequency (Hz) of every simulated
    voxel: the scene's fields where given, its scalars elsewhere."""
    def values(grid, scalar):
        return (np.full(len(idx), float(scalar)) if grid is None
                else grid[tuple(idx.T)].astype(np.float64))

    return (values(scene.youngs_modulus_field, scene.material.youngs_modulus),
            values(scene.density_field, scene.material.density),
            values(scene.frequency_field, scene.actuation.frequency))


def build_robot(scene: Scene) -> Robot:
    """Static arrays, parameters and initial momenta of one robot from a validated Scene.

    Per voxel i (E_i, rho_i from the fields or the scalars): m_i = rho_i L^3,
    I_i = m_i L^2 / 6, floor stiffness 2 E_i L, collision and global damping
    2 zeta sqrt(m_i E_i L) (angular: 2 zeta_global sqrt(I_i E_i L^3)). Per link j between
    voxels a, b: E_j = 2 E_a E_b / (E_a + E_b) (``series_modulus``), beam constants scaled by
    E_j / E_ref, bond damping gamma_j = 2 zeta_bond sqrt(m_j / (E_j L)) with
    m_j = (m_a + m_b) / 2. Step: dt = dt_fraction / (2 pi sqrt(max_j E_j L / min(m_a, m_b)))
    (``stable_dt`` exactly when every voxel has the same E and rho), capped at
    1 / (2000 f_max), f_max the highest frequency of an active voxel.
    """
    body = largest_component(scene.body)
    removed = int((scene.body > 0).sum() - (body > 0).sum())
    idx, lookup, nbr, link_neg, link_pos, link_axis, vlink = _lattice(body)
    n = len(idx)
    L = scene.voxel_size
    mat, env, act = scene.material, scene.environment, scene.actuation
    nu = mat.poisson_ratio
    E_v, rho_v, freq_v = voxel_values(scene, body, idx)
    mass = rho_v * L**3
    inertia = mass * L**2 / 6.0
    pos = (idx + 0.5) * L + np.array(scene.initial_offset)

    flags = np.where(body[tuple(idx.T)] == 2, FLAG_ACTIVE, 0).astype(np.int8)
    for v in scene.fixed:
        if lookup[tuple(v)] >= 0:
            flags[lookup[tuple(v)]] |= FLAG_FIXED
    ext = np.zeros((n, 3))
    for v, f in zip(scene.force_voxels, scene.force_values, strict=True):
        if lookup[tuple(v)] >= 0:
            ext[lookup[tuple(v)]] += f

    com = pos.mean(axis=0)
    omega = np.array(scene.initial_angular_velocity)
    vel = np.array(scene.initial_velocity) + np.cross(omega, pos - com)
    lin_mom = mass[:, None] * vel
    ang_mom = inertia[:, None] * omega
    fixed = (flags & FLAG_FIXED) > 0
    lin_mom[fixed] = 0.0
    ang_mom[fixed] = 0.0

    E_link = series_modulus(E_v[link_neg], E_v[link_pos])
    uniform = bool(np.all(E_v == E_v[0]) and np.all(rho_v == rho_v[0]))
    if uniform:
        dt = stable_dt(L, float(rho_v[0]), float(E_v[0]), scene.dt_fraction)
    else:
        if len(link_neg):
            rate = np.max(E_link * L / np.minimum(mass[link_neg], mass[link_pos]))
        else:
            rate = np.max(E_v * L / mass)
        dt = scene.dt_fraction / (2.0 * math.pi * math.sqrt(float(rate)))
    active = (flags & FLAG_ACTIVE) > 0
    f_active = freq_v[active]
    f_max = float(f_active.max()) if active.any() else act.frequency
    if f_max > 0 and active.any():
        dt = min(dt, 1.0 / (f_max * STEPS_PER_CYCLE))
    freq_field = bool(active.any() and not np.all(f_active == f_active[0]))
    f_common = float(f_active[0]) if active.any() else act.frequency
    settle_steps = int(round(scene.settle_seconds / dt))
    steps = settle_steps + int(math.ceil(scene.duration_seconds / dt - 1e-9))
    gravity = env.gravity
    E_ref = float(E_v.max())

    vc = np.zeros((n, N_VCONST))
    vc[:, V_MASS], vc[:, V_INV_MASS], vc[:, V_INV_INERTIA] = mass, 1.0 / mass, 1.0 / inertia
    vc[:, V_KFLOOR] = 2.0 * E_v * L
    sqrt_mel = np.sqrt(mass * E_v * L)
    vc[:, V_CCOLL] = 2.0 * mat.damping_collision * sqrt_mel
    vc[:, V_CGLIN] = 2.0 * mat.damping_global * sqrt_mel
    vc[:, V_CGANG] = 2.0 * mat.damping_global * np.sqrt(inertia * E_v * L**3)
    vc[:, V_OMEGA] = 2 * math.pi * freq_v
    vc[:, V_WEIGHT] = mass / mass.max()  # centre-of-mass weights (1.0 for one density)
    link_stiff = E_link / E_ref
    # Bond damping as stiffness-proportional (Rayleigh) damping: C = gamma K, which gives each
    # beam term the coefficient 2 zeta sqrt(m k) (sqrt(I k) for the rotational ones).
    m_link = 0.5 * (mass[link_neg] + mass[link_pos])
    gamma = 2.0 * mat.damping_bond * np.sqrt(m_link / (E_link * L))
    link_damp = gamma * 0.5 / dt

    f = np.zeros(N_FPARAMS)
    f[F_L] = L
    f[[F_A1, F_A2, F_B1, F_B2, F_B3]] = (
        E_ref * L, E_ref * L**3 / (12.0 * (1.0 + nu)), E_ref * L, E_ref * L**2 / 2.0,
        E_ref * L**3 / 6.0)
    f[[F_DT, F_GRAVITY]] = dt, gravity
    f[[F_MUS, F_MUK]] = mat.friction_static, mat.friction_kinetic
    f[F_DRAG] = 0.5 * env.fluid_density * env.drag_coefficient if env.kind == "water" else 0.0
    f[[F_OMEGA, F_AMP, F_SETTLE]] = 2 * math.pi * f_common, act.amplitude, scene.settle_seconds

    i = np.zeros(N_IPARAMS, dtype=np.int64)
    i[I_STEPS], i[I_SETTLE_STEPS] = steps, settle_steps
    i[I_ENV], i[I_WAVE] = ENV_CODES[env.kind], WAVE_CODES[act.waveform]
    i[I_RECORD] = scene.record_every
    i[I_COLLIDE] = int(scene.self_collisions)
    i[I_COM_EVERY] = max(1, (steps - settle_steps) // COM_SAMPLES)
    i[I_N_FRAMES] = (steps // scene.record_every + 1) if scene.record_every > 0 else 0
    i[I_FREQ_FIELD] = int(freq_field)

    surface = np.flatnonzero((nbr < 0).any(axis=1)).astype(np.int64)
    return Robot(idx, pos, flags, scene.phase[tuple(idx.T)].astype(np.float64), ext, lin_mom,
                 ang_mom, nbr, link_neg, link_pos, link_axis, vlink, surface, vc, link_stiff,
                 link_damp, f, i, removed)


def _offsets(counts) -> np.ndarray:
    return np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)


CONCATENATED = (  # Batch fields that are the robots' arrays one after another
    "flags", "ext_force", "nbr", "link_neg", "link_pos", "link_axis", "vlink", "surface",
    "vconst", "link_stiff", "link_damp",
)


def pack(robots: list[Robot]) -> tuple[Batch, State]:
    """Concatenate robots into one Batch and its initial State."""
    voff = _offsets([len(r.pos) for r in robots])
    phase = np.concatenate([r.phase for r in robots])
    batch = Batch(
        voff=voff,
        loff=_offsets([len(r.link_neg) for r in robots]),
        soff=_offsets([len(r.surface) for r in robots]),
        poff=_offsets([8 * len(r.surface) + 8 for r in robots]),
        cos_phase=np.cos(phase),
        sin_phase=np.sin(phase),
        phase=phase,
        fparams=np.stack([r.fparams for r in robots]),
        iparams=np.stack([r.iparams for r in robots]),
        **{name: np.concatenate([getattr(r, name) for r in robots]) for name in CONCATENATED},
    )
    n = int(voff[-1])
    quat = np.zeros((n, 4))
    quat[:, 0] = 1.0
    state = State(  # C order, as the kernels' flat views need
        pos=np.ascontiguousarray(np.concatenate([r.pos for r in robots])),
        quat=quat,
        lin_mom=np.ascontiguousarray(np.concatenate([r.lin_mom for r in robots])),
        ang_mom=np.ascontiguousarray(np.concatenate([r.ang_mom for r in robots])),
    )
    return batch, state
