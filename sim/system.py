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

from . import worlds
from .models import ModelOptions
from .scene import Scene

# Columns of the per-robot float parameter table ``fparams``.
F_L, F_A1, F_A2, F_B1, F_B2, F_B3, F_DT, F_GRAVITY, F_MUS, F_MUK = range(10)
F_DRAG, F_OMEGA, F_AMP, F_SETTLE, F_MESH_DRAG = range(10, 15)
F_CONTACT_REACH, F_CONTACT_STIFF, F_CONTACT_DAMP = range(15, 18)
N_FPARAMS = 18
# Columns of the per-robot integer parameter table ``iparams``.
I_STEPS, I_SETTLE_STEPS, I_ENV, I_WAVE, I_RECORD, I_COLLIDE, I_COM_EVERY, I_N_FRAMES = range(8)
I_FREQ_FIELD, I_ACT_START, I_FRICTION = 8, 9, 10
N_IPARAMS = 11
# Columns of the per-voxel constant table ``vconst`` (one row per voxel).
V_MASS, V_INV_MASS, V_INV_INERTIA, V_KFLOOR, V_CCOLL, V_CGLIN, V_CGANG, V_OMEGA = range(8)
V_WEIGHT = 8
N_VCONST = 9

ENV_LAND, ENV_WATER, ENV_VOID = 0, 1, 2
ENV_CODES = {worlds.LAND.name: ENV_LAND, worlds.WATER.name: ENV_WATER, worlds.VOID.name: ENV_VOID}
FRICTION_VOXELYZE2, FRICTION_VOXCAD = 0, 1
FRICTION_CODES = {"voxelyze-2": FRICTION_VOXELYZE2, "voxcad": FRICTION_VOXCAD}
WAVE_CODES = {"sine": 0, "square": 1, "impulse": 2}
# voxelyze-2: the step resolves an actuation cycle at least this finely (a model option)
STEPS_PER_CYCLE = ModelOptions.min_steps_per_cycle
COM_SAMPLES = 200  # centre-of-mass samples kept per run (plus the start)
FLAG_FIXED, FLAG_ACTIVE = 1, 2
# how a robot's run ended (every engine writes one per robot; ``sim.result`` reads it)
STATUS_OK, STATUS_STRAIN, STATUS_NONFINITE, STATUS_CONTACTS = 0, 1, 2, 3
# self-contact candidates a voxel may have (the contact policy: ``sim.physics``)
MAX_CONTACTS = 64


FACE_CONNECTED = ndimage.generate_binary_structure(3, 1)  # label's default in 3-D, made once


def largest_component(body: np.ndarray) -> np.ndarray:
    """Keep only the largest face-connected component of full voxels (ties: lowest label)."""
    labels, n = ndimage.label(body > 0, FACE_CONNECTED if body.ndim == 3 else None)
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
    settle: float  # settling time before the centre-of-mass reference is taken, s
    mesh_drag: float  # water drag on the deformed surface mesh: 0.5 rho_fluid C_d (0: none)
    contact_reach: float  # self-contact begins at this times the sum of the two sizes
    contact_stiff: float  # self-contact stiffness: this times the harmonic mean of 2 E L
    contact_damp: float  # self-contact damping: this times the collision damping
    steps: int  # total steps, settling included
    settle_steps: int
    env: int  # ENV_LAND, ENV_WATER or ENV_VOID
    wave: int  # WAVE_CODES
    record: int  # record a frame every this many steps (0: none)
    collide: int  # 1: self-collisions on
    com_every: int  # a centre-of-mass sample every this many steps after settling
    n_frames: int  # frames recorded over the whole run
    freq_field: int  # 1: active voxels have frequencies of their own (``vconst[:, V_OMEGA]``)
    act_start: int  # the step at which actuation starts (its clock reads 0 there)
    friction: int  # FRICTION_VOXELYZE2 or FRICTION_VOXCAD (the floor's friction rule)


def params_of(fp, ip) -> Params:
    """A robot's ``Params`` from its rows of ``Batch.fparams`` and ``Batch.iparams`` (plain
    Python, compiled by each engine: ``kernels.params``, ``cuda_kernels.params``)."""
    return Params(
        fp[F_L], fp[F_A1], fp[F_A2], fp[F_B1], fp[F_B2], fp[F_B3], fp[F_DT], fp[F_GRAVITY],
        fp[F_MUS], fp[F_MUK], fp[F_DRAG], fp[F_OMEGA], fp[F_AMP], fp[F_SETTLE], fp[F_MESH_DRAG],
        fp[F_CONTACT_REACH], fp[F_CONTACT_STIFF], fp[F_CONTACT_DAMP],
        ip[I_STEPS], ip[I_SETTLE_STEPS], ip[I_ENV], ip[I_WAVE], ip[I_RECORD], ip[I_COLLIDE],
        ip[I_COM_EVERY], ip[I_N_FRAMES], ip[I_FREQ_FIELD], ip[I_ACT_START], ip[I_FRICTION])


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
    near: np.ndarray  # (n, k) int64 voxels never in contact with each voxel (-1: none)
    mesh_vert: np.ndarray  # (nv, 8) int64 8 voxel + corner of each surface-mesh vertex (-1: none)
    mesh_face: np.ndarray  # (nf, 4) int64 a mesh triangle's 3 vertices and its voxel
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
    moff: np.ndarray  # (R + 1,) int64 into ``mesh_vert``
    foff: np.ndarray  # (R + 1,) int64 into ``mesh_face``
    poff: np.ndarray  # (R + 1,) int64 into the collision pair buffer
    flags: np.ndarray
    cos_phase: np.ndarray
    sin_phase: np.ndarray
    phase: np.ndarray
    ext_force: np.ndarray
    nbr: np.ndarray  # voxel indices within the robot (-1: exposed face)
    exposed: np.ndarray  # (N,) int64 bit f set: face f exposed (``exposed_faces``)
    link_neg: np.ndarray  # voxel indices within the robot
    link_pos: np.ndarray
    link_axis: np.ndarray
    vlink: np.ndarray  # link indices within the robot (its link count m: no link on that face)
    surface: np.ndarray  # voxel indices within the robot
    near: np.ndarray  # (N, K) voxel indices within the robot (-1: none), K the batch's widest
    mesh_vert: np.ndarray  # (NV, 8) 8 voxel + corner, voxels within the robot (-1: none)
    mesh_face: np.ndarray  # (NF, 4) vertex indices within the robot's mesh, voxel within it
    vconst: np.ndarray  # (N, N_VCONST)
    link_stiff: np.ndarray  # (M,)
    link_damp: np.ndarray  # (M,)
    fparams: np.ndarray  # (R, N_FPARAMS)
    iparams: np.ndarray  # (R, N_IPARAMS)


class State(NamedTuple):
    """Dynamic state of a batch (updated in place by the kernel). The numba engine runs each
    robot on private copies by component, one row each: (3, n) and (4, n), so that the voxel
    update's vector loop reads and writes contiguous rows (``kernels.take_robot``); the
    batch's arrays, and every caller's, are (N, 3) and (N, 4)."""

    pos: np.ndarray  # (N, 3)
    quat: np.ndarray  # (N, 4)
    lin_mom: np.ndarray  # (N, 3)
    ang_mom: np.ndarray  # (N, 3)


def _lattice(body: np.ndarray):
    """(idx, lookup, nbr, link_neg, link_pos, link_axis, vlink) of a body's full voxels: their
    (n, 3) lattice indices in x-major order, the (X, Y, Z) index of each cell's voxel (-1
    empty), each voxel's (n, 6) face neighbours (-x, +x, -y, +y, -z, +z; -1 none), the (m,)
    links axis by axis, voxel by voxel, and each voxel's (n, 6) link per face (m: none)."""
    from .tables import lattice_tables  # numba: loaded by the engines, not by sim's users

    return lattice_tables(np.ascontiguousarray(np.asarray(body) > 0))


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
    1 / (n f_max), f_max the highest frequency of an active voxel and n the model's
    ``min_steps_per_cycle`` (2000; none in the paper's engine).

    The model's switches (``scene.options``): the angular global damping times
    ``rotation_damping``; contact never between voxels within ``collision_horizon`` bond hops
    (``nearby``); actuation from step ``act_start`` (0 or the settling steps) and, with the
    absolute clock, each phase advanced by omega_i times the start time (so the sine reads
    the time since t = 0); in water with ``drag`` "mesh", the drag acts on the triangles of
    the deformed surface mesh (``surface_mesh``) instead of each voxel's own faces.
    """
    opts = scene.options
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
    arm = pos - com
    spin = np.column_stack([omega[1] * arm[:, 2] - omega[2] * arm[:, 1],  # omega x arm, as np.cross
                            omega[2] * arm[:, 0] - omega[0] * arm[:, 2],  # computes it (a tenth of
                            omega[0] * arm[:, 1] - omega[1] * arm[:, 0]])  # its time for one vector)
    vel = np.array(scene.initial_velocity) + spin
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
    dt = cycle_capped_dt(dt, f_active, opts.min_steps_per_cycle)
    freq_field = bool(active.any() and not np.all(f_active == f_active[0]))
    f_common = float(f_active[0]) if active.any() else act.frequency
    settle_steps, steps = step_counts(scene, dt)
    gravity = env.gravity
    E_ref = float(E_v.max())

    vc = np.zeros((n, N_VCONST))
    vc[:, V_MASS], vc[:, V_INV_MASS], vc[:, V_INV_INERTIA] = mass, 1.0 / mass, 1.0 / inertia
    vc[:, V_KFLOOR] = 2.0 * E_v * L
    sqrt_mel = np.sqrt(mass * E_v * L)
    vc[:, V_CCOLL] = 2.0 * mat.damping_collision * sqrt_mel
    vc[:, V_CGLIN] = 2.0 * mat.damping_global * sqrt_mel
    vc[:, V_CGANG] = (2.0 * opts.rotation_damping * mat.damping_global
                      * np.sqrt(inertia * E_v * L**3))
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
    drag = 0.5 * env.fluid_density * env.drag_coefficient if worlds.get(env.kind).drag else 0.0
    mesh = opts.drag == "mesh" and drag > 0.0
    f[F_DRAG], f[F_MESH_DRAG] = (0.0, drag) if mesh else (drag, 0.0)
    f[[F_OMEGA, F_AMP, F_SETTLE]] = 2 * math.pi * f_common, act.amplitude, scene.settle_seconds
    # self-contact: voxelyze-2 touches at the sum of half sizes with the floor's stiffness,
    # damped; the fork's spheres of 1.5 voxels repel with the bond's a1 = E_link L, undamped
    f[[F_CONTACT_REACH, F_CONTACT_STIFF, F_CONTACT_DAMP]] = (
        (0.5, 1.0, 1.0) if opts.contact == "voxelyze-2" else (0.75, 0.5, 0.0))

    i = np.zeros(N_IPARAMS, dtype=np.int64)
    i[I_STEPS], i[I_SETTLE_STEPS] = steps, settle_steps
    i[I_ENV], i[I_WAVE] = ENV_CODES[env.kind], WAVE_CODES[act.waveform]
    i[I_RECORD] = scene.record_every
    i[I_COLLIDE] = int(scene.self_collisions)
    i[I_COM_EVERY] = max(1, (steps - settle_steps) // COM_SAMPLES)
    i[I_N_FRAMES] = (steps // scene.record_every + 1) if scene.record_every > 0 else 0
    i[I_FREQ_FIELD] = int(freq_field)
    start = settle_steps if opts.actuation_start == "settled" else 0
    i[I_ACT_START] = start + opts.actuation_lag
    i[I_FRICTION] = FRICTION_CODES[opts.friction]
    phase = scene.phase[tuple(idx.T)].astype(np.float64)
    if opts.actuation_clock == "absolute":
        phase = phase + vc[:, V_OMEGA] * (start * dt)

    surface = np.flatnonzero((nbr < 0).any(axis=1)).astype(np.int64)
    near = nearby(nbr, opts.collision_horizon) if scene.self_collisions else nbr
    mesh_vert, mesh_face = surface_mesh(idx, lookup, nbr) if mesh else (
        np.zeros((0, 8), np.int64), np.zeros((0, 4), np.int64))
    return Robot(idx, pos, flags, phase, ext, lin_mom, ang_mom, nbr, link_neg, link_pos,
                 link_axis, vlink, surface, near, mesh_vert, mesh_face, vc, link_stiff,
                 link_damp, f, i, removed)


def cycle_capped_dt(dt: float, active_frequencies: np.ndarray, min_steps_per_cycle: int) -> float:
    """``dt`` (s) capped at 1 / (n f_max): f_max the highest of ``active_frequencies`` (Hz,
    one per active voxel) and n ``min_steps_per_cycle`` (0: no cap; no cap without an active
    voxel or with f_max 0)."""
    if len(active_frequencies) == 0 or min_steps_per_cycle <= 0:
        return dt
    f_max = float(np.max(active_frequencies))
    return min(dt, 1.0 / (f_max * min_steps_per_cycle)) if f_max > 0 else dt


MIN_RESOLVED_STEPS_PER_CYCLE = 20
"""The fewest steps per actuation cycle the engine simulates: a faster robot is aliased (at
11,804 Hz the fork's step of a stiff robot sees less than one step per cycle), and every engine
refuses it unrun (``sim.result.prepare``), whatever its model's ``min_steps_per_cycle``."""


def steps_per_cycle(robot: Robot) -> float:
    """Steps of ``robot``'s step ``dt`` per cycle of its fastest active voxel (inf without an
    active voxel or with a frequency of 0)."""
    active = (robot.flags & FLAG_ACTIVE) > 0
    if not active.any():
        return math.inf
    omega = float(np.max(robot.vconst[active, V_OMEGA]))
    return math.inf if omega <= 0 else 2.0 * math.pi / (omega * float(robot.fparams[F_DT]))


def step_counts(scene: Scene, dt: float) -> tuple[int, int]:
    """(settling steps, total steps) of ``scene`` at step ``dt`` (s): the settling seconds
    rounded, then the duration's steps rounded up. OverflowError if the total exceeds an
    int64 (``duration.cycles: 1e300``): the engine counts its steps in one."""
    settle = int(round(scene.settle_seconds / dt))
    total = settle + int(math.ceil(scene.duration_seconds / dt - 1e-9))
    if total > np.iinfo(np.int64).max:
        raise OverflowError(f"{total:.3g} steps do not fit an int64")
    return settle, total


def scene_dt(scene: Scene) -> float:
    """The engine's step for a validated scene, seconds (``build_robot``'s own): the model's
    stability step from stiffness, density and ``dt_fraction`` (``stable_dt`` when every voxel
    has one material), capped by its ``min_steps_per_cycle`` (``cycle_capped_dt``). Without
    stiffness or density fields it is computed from the scalars, without building the robot."""
    body = largest_component(scene.body)
    if np.any(body) and (scene.youngs_modulus_field is not None or scene.density_field is not None):
        return float(build_robot(scene).fparams[F_DT])
    active = body == 2
    if scene.frequency_field is not None:
        frequencies = scene.frequency_field[active]
    else:
        frequencies = np.full(int(active.sum()), float(scene.actuation.frequency))
    dt = stable_dt(scene.voxel_size, scene.material.density, scene.material.youngs_modulus,
                   scene.dt_fraction)
    return cycle_capped_dt(dt, frequencies, scene.options.min_steps_per_cycle)


def scene_steps(scene: Scene) -> int:
    """Steps the engine takes for a validated scene, settling included (``build_robot``'s own
    count: ``step_counts`` at ``scene_dt``); 0 for an empty body. The one step count of the
    project: the cost model, the size limits (``service.runs.limits``) and the workers' frame
    budget read it. OverflowError if the count exceeds an int64 (``duration.cycles: 1e300``)."""
    if not np.any(scene.body):
        return 0
    return step_counts(scene, scene_dt(scene))[1]


def nearby(nbr: np.ndarray, hops: int) -> np.ndarray:
    """Each voxel's voxels within ``hops`` bond hops, itself left out (the paper's engine:
    CalcNearby, walking bonds only, never across a gap): each row ascending, padded with -1
    at its end (the kernels' ``listed`` stops at the first entry past the one it looks for).
    One hop: the face neighbours ``nbr`` (the bonded voxels), sorted."""
    if hops <= 1:
        rows = np.sort(np.where(nbr >= 0, nbr, np.iinfo(np.int64).max), axis=1)
        return np.where(rows == np.iinfo(np.int64).max, -1, rows).astype(np.int64)
    from .tables import within_hops  # numba: loaded by the engines, not by sim's users

    return within_hops(np.ascontiguousarray(nbr, dtype=np.int64), int(hops))


# The surface mesh of the paper's engine: two triangles per exposed face, each vertex a
# lattice corner. Corners are (dx, dy, dz) in {0, 1}^3 of a voxel's cell, as code 4 dx + 2 dy
# + dz; each face's triangles, by its face (ordered as ``nbr``: -x, +x, -y, +y, -z, +z), with
# vertices counter-clockwise seen from outside (the normal (b - a) x (c - a) points out) and
# the diagonal through the cell's lowest corner of that face, as the fork triangulates.
FACE_TRIANGLES = (
    ((0b000, 0b011, 0b010), (0b000, 0b001, 0b011)),
    ((0b100, 0b110, 0b111), (0b100, 0b111, 0b101)),
    ((0b000, 0b101, 0b001), (0b000, 0b100, 0b101)),
    ((0b010, 0b011, 0b111), (0b010, 0b111, 0b110)),
    ((0b000, 0b110, 0b100), (0b000, 0b010, 0b110)),
    ((0b001, 0b101, 0b111), (0b001, 0b111, 0b011)),
)


_CORNERS = np.array([[(c >> 2) & 1, (c >> 1) & 1, c & 1] for c in range(8)])  # code -> (dx, dy, dz)


def surface_mesh(idx: np.ndarray, lookup: np.ndarray, nbr: np.ndarray):
    """The vertices and triangles of a robot's surface mesh.

    ``mesh_vert`` (nv, 8): for each vertex, 8 voxel + corner of every voxel whose cell has
    that lattice corner (-1 pads); its position is the mean over them of the voxel's centre
    plus its rotated corner (``kernels.mesh_vertices_kernel``). ``mesh_face`` (nf, 4): a
    triangle's three vertices and the voxel whose exposed face it covers. Faces come voxel by
    voxel (in ``idx`` order), face by face (in ``nbr`` order), two triangles each, in
    consecutive rows that start at the same vertex (``FACE_TRIANGLES``; the CPU's drag reads
    a face's pair at once); vertices are numbered in the order the triangles first meet
    them, and list their voxels in corner order."""
    from .tables import surface_mesh_tables  # numba: loaded by the engines, not by sim's users

    return surface_mesh_tables(np.ascontiguousarray(idx, dtype=np.int64), lookup.astype(np.int64),
                               nbr.astype(np.int64), np.asarray(FACE_TRIANGLES, dtype=np.int64),
                               _CORNERS)


def _offsets(counts) -> np.ndarray:
    return np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)


CONCATENATED = (  # Batch fields that are the robots' arrays one after another
    "flags", "ext_force", "nbr", "link_neg", "link_pos", "link_axis", "vlink", "surface",
    "mesh_vert", "mesh_face", "vconst", "link_stiff", "link_damp",
)


def _padded(tables: list[np.ndarray]) -> np.ndarray:
    """Row tables of different widths one after another, padded with -1 to the widest."""
    out = np.full((sum(len(t) for t in tables), max(t.shape[1] for t in tables)), -1, np.int64)
    start = 0
    for table in tables:
        out[start : start + len(table), : table.shape[1]] = table
        start += len(table)
    return out


def exposed_faces(nbr: np.ndarray) -> np.ndarray:
    """Each voxel's exposed faces as bits: bit f set when face f (ordered as ``nbr``: -x, +x,
    -y, +y, -z, +z) has no neighbour. Both engines' drag on exposed faces reads it
    (``physics.face_drag``)."""
    return ((nbr < 0) * (1 << np.arange(6))).sum(axis=1).astype(np.int64)


def pack(robots: list[Robot]) -> tuple[Batch, State]:
    """Concatenate robots into one Batch and its initial State."""
    voff = _offsets([len(r.pos) for r in robots])
    phase = np.concatenate([r.phase for r in robots])
    nbr = np.concatenate([r.nbr for r in robots])
    batch = Batch(
        voff=voff,
        loff=_offsets([len(r.link_neg) for r in robots]),
        soff=_offsets([len(r.surface) for r in robots]),
        moff=_offsets([len(r.mesh_vert) for r in robots]),
        foff=_offsets([len(r.mesh_face) for r in robots]),
        near=_padded([r.near for r in robots]),
        poff=_offsets([len(r.surface) * MAX_CONTACTS // 2 + 1 for r in robots]),
        cos_phase=np.cos(phase),
        sin_phase=np.sin(phase),
        phase=phase,
        exposed=exposed_faces(nbr),
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
