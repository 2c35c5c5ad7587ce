"""Compiled kernels: the whole rollout of many robots in one call.

``run_batch`` runs each robot as one task of a ``prange``; ``run_robot`` loops over the steps,
takes frames and centre-of-mass samples (``sample``) and stops at the first failure
(``physics.step_status``); ``step`` is one step, its sub-steps named as the GPU engine's:

    actuate -> link_forces -> contact_list -> contact_forces -> mesh_vertices -> mesh_drag
    -> voxel_update (world forces, floor, integrate)

- ``actuate``: voxel size s = max(L (1 + amp w(omega t + phase)), 0.1 L) for active voxels;
- ``link_forces``: co-rotational 3-D beams (``link_kernel``: gather, then one SIMD loop per
  frame over the links kept in that frame's run; ``change_frames`` for the few that switch),
  summed per voxel (``link_sums``); stiffness-proportional bond damping;
- ``contact_list``: the self-contact candidates, rebuilt when stale (the policy:
  ``sim.physics``); ``contact_forces``: penalty contact k overlap - c v_n (>= 0) between
  candidates, surface voxels that are not within the model's collision horizon (bonded pairs
  in voxelyze-2; ``Voxels.near``);
- ``mesh_vertices``, ``mesh_drag`` (water, the paper's engine's model): drag on the
  triangles of the deformed surface mesh; otherwise ``voxel_update`` puts the drag on each
  voxel's exposed faces;
- ``voxel_update``, one branch-free SIMD pass over the voxels (``voxel_update_kernel``; a second
  pass gives the few voxels that turn past the quaternion series their exact rotation):
  - world forces: gravity -m g z, global damping -c_lin v and -c_ang omega, in water the
    quadratic drag -0.5 rho C_d s^2 v_n^2 n on exposed faces moving outward (v_n > 0);
  - floor contact: on land, normal force k_floor pen - c_coll v_z for pen = s/2 - z >= 0,
    static friction up to mu_s N, kinetic friction mu_k N against the horizontal velocity;
  - integration: semi-implicit Euler, p += F dt then x += p / m dt, and L += M dt then
    q = exp(L / I dt) q (renormalised); a sliding voxel in floor contact sticks when
    friction would reverse it.

What the two engines share is written once and inlined here: the formulas and every
per-element body of the step (``sim.physics``, scalar functions: a voxel's actuated size, a
link's frame, its hysteresis transition, damping and loads, a voxel's sum of its links'
loads, the rebuild trigger of the contact list, a facet's normal and drag, a mesh corner, a
voxel's update, the sampling and the order of the failure checks) and the few that index
arrays (``sim.substeps``: the candidate test, a pair's contact force). This module holds
what is the CPU's own: the loops, the memory layout (the link buffer's tiles and its two
runs by frame, which split a frame change into a mark and a second pass: ``change_frames``),
the sweep over sorted surface voxels that lists the candidates, and every voxel's mesh
corners kept for a vector loop. A robot's constants are a ``Params`` named tuple
(``sim.system``); its arrays are grouped as ``Voxels``, ``Links``, its body state as
``State`` and its scratch as ``Work``, all private copies of its slices of the batch
(indices local to the robot). Each sub-step is an inlined wrapper around a compiled loop
(``actuate_kernel``, ``link_kernel`` ...) that takes the arrays it uses one by one. All
state is struct-of-arrays; no Python runs per voxel or per step. An array passed to a helper
can cost two atomic reference-count updates per call, which once took most of the link
loop's time: the physics takes and returns scalars only, the helpers that read arrays are
inlined, and the step loop runs on views that count no references (``borrow``).

Materials and frequencies per voxel (scene fields ``youngs_modulus_field``, ``density_field``,
``frequency_field``; without them every voxel has the scalar values). Voxel i has E_i, rho_i,
f_i; L is the voxel size, nu Poisson's ratio (one for the robot):
- mass m_i = rho_i L^3, inertia I_i = m_i L^2 / 6 (integration, gravity m_i g);
- floor stiffness 2 E_i L; collision damping c_i = 2 zeta_coll sqrt(m_i E_i L) (floor);
  global damping -2 zeta_glob sqrt(m_i E_i L) v and -2 zeta_glob sqrt(I_i E_i L^3) omega;
  friction from each voxel's own normal force; self-contact of voxels i, j: stiffness the
  harmonic mean of 2 E_i L and 2 E_j L, damping (c_i + c_j) / 2 on the relative normal
  velocity v_j - v_i;
- a link between voxels a and b is two half-beams of length L/2 in series:
  E_link = 2 E_a E_b / (E_a + E_b) (exactly E when E_a = E_b); its beam constants are those
  of docs/physics.md with E_link: a1 = b1 = E_link L, a2 = E_link L^3 / (12 (1 + nu)),
  b2 = E_link L^2 / 2, b3 = E_link L^3 / 6, computed as the robot's reference constants
  (``Params.a1`` ..., of E_ref = the largest E_i) times ``link_stiff`` = E_link / E_ref;
  bond damping gamma_link = 2 zeta_bond sqrt(m_link / (E_link L)), m_link = (m_a + m_b) / 2,
  so each beam term k gets 2 zeta_bond sqrt(m_link k);
- step: dt = dt_fraction / (2 pi sqrt(max over links of E_link L / min(m_a, m_b)))
  (= dt_fraction L sqrt(rho / E) / (2 pi) for one material), capped at 1 / (2000 f_max);
- actuation: active voxel i has size L (1 + a w(2 pi f_i t + phase_i)); when all active voxels
  share one f (no field or a uniform one) the step computes sin(2 pi f t) once and combines it
  with each voxel's phase (no libm per voxel); a scene's ``duration.cycles`` counts cycles of
  the mean f_i over active voxels (``sim.scene``);
- centre of mass: weighted by m_i.

Maths conventions: quaternions are (w, x, y, z); a link's local frame has x along the link
(see ``to_link``); rotation vectors are axis * angle in radians.
"""

from __future__ import annotations

import inspect
import math
import warnings
from typing import NamedTuple

import llvmlite.binding
import llvmlite.ir
import numpy as np
from numba import njit, prange, types
from numba.core import cgutils
from numba.core.errors import NumbaIRAssumptionWarning
from numba.extending import intrinsic, overload

from . import physics, substeps
from .physics import (  # noqa: F401 (the engine reports MAX_STRAIN)
    ACT_FIELD,
    ACT_REST,
    ACT_SINE,
    ACT_WAVE,
    COLLIDE_MARGIN,
    MAX_STRAIN,
    POSITION_BOUND,
)
from .system import (
    FLAG_ACTIVE,
    FLAG_FIXED,
    MAX_CONTACTS,
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
    State,
    params_of,
)

# fastmath without 'nnan'/'ninf' (divergence stays detectable by comparisons) and without
# 'reassoc'/'contract': with those, a freshly compiled kernel and the same kernel loaded from
# numba's cache round differently, and the same seed must give the same run in every process.
# The hot products are fused by hand instead (``fma``, ``dot3``), which rounds the same way in
# every process.
FASTMATH = {"arcp", "nsz", "afn"}
JIT = dict(cache=True, fastmath=FASTMATH, error_model="numpy")
INLINE = dict(inline="always", **JIT)

# The link loop's vectorized form needs LLVM to emit more runtime alias checks than its default
# budget of 128 (one per pair of link rows that could overlap); a process-wide setting that only
# lets the vectorizer take loops it would otherwise leave scalar.
llvmlite.binding.set_option("softevo", "-vectorize-memory-check-threshold=1024")
# The mixed precision's float32 link loop: LLVM sizes a loop's vectors by its widest type (the
# 64-bit offsets), so it ran 8 float32 lanes where 16 fit; with this it may take the wider
# form where its cost model says so (issue 47: float64 code measured unchanged, the mixed
# quadruped about 6% faster). Process-wide, like the setting above.
llvmlite.binding.set_option("softevo", "-vectorizer-maximize-bandwidth")
# The voxel update's vector loop (``voxel_pass``) reads and writes some 30 strided locations,
# each needing a runtime check that its offsets do not wrap: more than LLVM's default budget
# of 16 such assumptions. Process-wide, like the settings above.
llvmlite.binding.set_option("softevo", "-vectorize-scev-check-threshold=256")


@intrinsic
def fma(typingctx, a, b, c):
    """a * b + c with one rounding (LLVM's fma: one instruction on CPUs with FMA, vectorized
    with the loop). Explicit, so its results do not depend on how or when a kernel was
    compiled, as LLVM's own contraction ('contract' above) would. In float32 when all three
    are float32 (the mixed precision's link loop), else in float64."""
    if not all(isinstance(t, types.Float) for t in (a, b, c)):
        return None
    single = all(t == types.float32 for t in (a, b, c))
    real = types.float32 if single else types.float64
    sig = real(real, real, real)

    def codegen(context, builder, signature, args):
        args = [context.cast(builder, v, t, real)
                for v, t in zip(args, signature.args, strict=True)]
        ir_real = llvmlite.ir.FloatType() if single else llvmlite.ir.DoubleType()
        fn = cgutils.get_or_insert_function(
            builder.module, llvmlite.ir.FunctionType(ir_real, [ir_real] * 3),
            "llvm.fma.f32" if single else "llvm.fma.f64")
        return builder.call(fn, args)

    return sig, codegen


@intrinsic
def wide_vectors(typingctx):
    """Nothing at run time; it marks the function that calls it (its LLVM attributes
    "prefer-vector-width" and "min-legal-vector-width") to take vectors of up to 512 bits
    where the CPU has them. LLVM's default for AVX-512 CPUs of the Intel line is 256 bits,
    which the other loops keep (their 512-bit forms measured no faster); the link loops,
    bound by their arithmetic, run 10-15% faster in 512 (docs/benchmarks.md). Without
    AVX-512 the attributes change nothing."""

    def codegen(context, builder, signature, args):
        attributes = builder.function.attributes
        # llvmlite's set of attributes takes only flags; these two are LLVM's string ones
        set.add(attributes, '"prefer-vector-width"="512"')
        set.add(attributes, '"min-legal-vector-width"="512"')
        return context.get_dummy_value()

    return types.none(), codegen


# The physics, compiled for this target (``sim.physics``): inlined into the loops below, in
# float64, and the link's pieces in float32 too for the mixed precision (``by_precision``).
_INLINE_PHYSICS = njit(inline="always", fastmath=FASTMATH, error_model="numpy")
_phys = physics.compiled(_INLINE_PHYSICS, fma)
_phys32 = physics.compiled(_INLINE_PHYSICS, fma, real=np.float32)


def _single(t) -> bool:
    """Whether the numba type t is float32 or a tuple holding one."""
    return t == types.float32 or (isinstance(t, types.BaseTuple) and types.float32 in t.types)


# Inlining the pieces that ``by_precision`` dispatches trips a pedantic check of numba's IR
# (a variable of an inlined piece "not in scope"); the compiled code is right (the kernels'
# tests), so that one warning is not shown to every user who compiles the kernels.
warnings.filterwarnings("ignore", message="variable '.*' is not in scope",
                        category=NumbaIRAssumptionWarning)


def by_precision(name):
    """The physics piece ``name`` in both precisions as one function: its float32 copy when any
    argument is float32 (a link of the mixed precision: its buffer is float32), else its
    float64 one. The choice is made when a caller is compiled, per argument types."""
    f64, f32 = getattr(_phys, name), getattr(_phys32, name)
    params = ", ".join(inspect.signature(getattr(physics, name)).parameters)
    scope: dict = {"pick": lambda args: (f32 if any(map(_single, args)) else f64).py_func}
    exec(f"def {name}({params}):\n    raise NotImplementedError('compiled code only')\n"
         f"def choose({params}):\n    return pick(({params},))", scope)
    stub = scope[name]
    overload(stub, inline="always", jit_options=dict(fastmath=FASTMATH, error_model="numpy"))(
        scope["choose"])
    return stub


dot3, qmul, qrot, rotvec = _phys.dot3, _phys.qmul, _phys.qrot, _phys.rotvec
quat_from_rotvec, rotation_matrix = _phys.quat_from_rotvec, _phys.rotation_matrix
quat_from_small_rotvec, voxel_turn = _phys.quat_from_small_rotvec, _phys.voxel_turn
actuation, voxel_size = _phys.actuation, _phys.voxel_size
link_geometry_of, link_frame = by_precision("link_geometry"), by_precision("link_frame")
reframe, link_response = by_precision("reframe"), by_precision("link_response")
frame_damping, rest_length = by_precision("frame_damping"), _phys.rest_length
voxel_loads, candidate_radius = _phys.voxel_loads, _phys.candidate_radius
contacts_stale, travel_after, widen = _phys.contacts_stale, _phys.travel_after, _phys.widen
displacement_spread, facet_force_of = _phys.displacement_spread, _phys.facet_force
corner_extents, mesh_corner, corner_point = _phys.corner_extents, _phys.mesh_corner, _phys.corner_point
voxel_update_of, voxel_world = _phys.voxel_update, _phys.voxel_world
centre_of_mass, frame_due, com_due = _phys.centre_of_mass, _phys.frame_due, _phys.com_due
step_status = _phys.step_status
# the array-reading pieces both engines share (``sim.substeps``)
_sub = substeps.compiled(_INLINE_PHYSICS, _phys)
listed, is_candidate, pair_force = _sub.listed, _sub.is_candidate, _sub.pair_force


@njit(**INLINE)
def voxel_sizes(mode, t, p, flags, cos_phase, sin_phase, phase, vconst, size, s_wt, c_wt):
    """Every voxel's ``physics.voxel_size`` into ``size``, for one actuation mode."""
    for v in range(len(size)):
        size[v] = voxel_size(p, mode, t, flags[v] & FLAG_ACTIVE != 0, vconst[v, V_OMEGA],
                             phase[v], cos_phase[v], sin_phase[v], s_wt, c_wt)


@njit(**JIT)
def actuate_kernel(t, p, flags, cos_phase, sin_phase, phase, vconst, size):
    """Current size of every voxel at time t (t < 0: no actuation yet): ``physics.actuation``
    and ``physics.voxel_size``. One loop per mode, each with its mode a constant, so that
    LLVM drops the other modes' branches from it (and vectorizes the sine's)."""
    mode, s_wt, c_wt = actuation(p, t)
    if mode == ACT_REST:
        voxel_sizes(ACT_REST, t, p, flags, cos_phase, sin_phase, phase, vconst, size, s_wt, c_wt)
    elif mode == ACT_FIELD:
        voxel_sizes(ACT_FIELD, t, p, flags, cos_phase, sin_phase, phase, vconst, size, s_wt, c_wt)
    elif mode == ACT_SINE:
        voxel_sizes(ACT_SINE, t, p, flags, cos_phase, sin_phase, phase, vconst, size, s_wt, c_wt)
    else:
        voxel_sizes(ACT_WAVE, t, p, flags, cos_phase, sin_phase, phase, vconst, size, s_wt, c_wt)


# ---------------------------------------------------------------- links
# One flat buffer per robot holds everything the link loops read and write, in tiles of
# LINK_TILE places: tile t holds LINK_ROWS rows of LINK_TILE values, row k of the link at
# place j of the tile at offset (t LINK_ROWS + k) LINK_TILE + j (``place`` and ``at``). Rows are
# a compile-time constant apart, so LLVM proves the rows of a loop over a tile apart by itself
# (rows a run-time stride apart would put some 400 run-time overlap checks in front of each
# link loop: docs/benchmarks.md). LINK_TILE is 8 values past a multiple of 512 so that the
# rows of a tile start on different cache-line sets (with 1024 every row maps onto the same
# few sets: over twice as slow). Moving a link to another place (``swap_links``) is one loop
# over rows. Place m (m links) stays 0 in every row: ``link_sums`` reads it for a face
# without a link.
LINK_IN_ROWS = 12  # both orientations (4 + 4), centre offset (3), rest length
LINK_STATE_ROWS = 10  # previous elongation (3) and end rotations (3 + 3); frame mode
# (row 3, the first end's x rotation, stays 0: the turn onto the centre line has none)
LINK_OUT_ROWS = 9  # force on the negative end, moment on the negative end, on the positive end
LINK_CONST_ROWS = 3  # axis (0., 1., 2.), stiffness scale E_link / E_ref, bond damping
ROW_STATE = LINK_IN_ROWS  # the input rows come first
ROW_OUT = ROW_STATE + LINK_STATE_ROWS
ROW_CONST = ROW_OUT + LINK_OUT_ROWS
LINK_ROWS = ROW_CONST + LINK_CONST_ROWS
LINK_TILE = 1032  # places per tile: 2 * 512 + 8
ROW_MODE = ROW_STATE + 9  # frame mode: +1 small-angle, -1 large, 0 before the first step
ROW_AXIS, ROW_STIFF, ROW_DAMP = ROW_CONST, ROW_CONST + 1, ROW_CONST + 2
# the mode a frame loop leaves on a link that must be computed again in the other frame
LEAVES, RETURNS = 2.0, -2.0
MOVED = 1 << 32  # a link that changes frame, in link_kernel's count
CHANGE_BLOCK = 64  # links per block of change_frames' search


@njit(**INLINE)
def place(j):
    """Offset of place j in the first row of its tile (unsigned)."""
    U = np.uint64
    t = U(j) // U(LINK_TILE)  # unsigned: a multiply and a shift
    return t * U((LINK_ROWS - 1) * LINK_TILE) + U(j)


@njit(**INLINE)
def at(row, J):
    """Offset of row ``row`` of the place at offset J (from ``place``)."""
    return np.uint64(row * LINK_TILE) + J


@njit(**INLINE)
def link_buffer_size(m):
    """Values in the buffer of m links: whole tiles for m + 1 places (the last one zero)."""
    return (m // LINK_TILE + 1) * LINK_ROWS * LINK_TILE


@njit(**INLINE)
def link_inputs(B, J):
    """Link J's geometry (``physics.link_geometry``: R, and the centre offset and relative
    rotation in the link frame), axis and rest length, from the buffer's input rows."""
    ax = B[at(ROW_AXIS, J)]
    R, rx, ry, rz, ow, ox, oy, oz = link_geometry_of(
        B[at(0, J)], B[at(1, J)], B[at(2, J)], B[at(3, J)], B[at(4, J)], B[at(5, J)],
        B[at(6, J)], B[at(7, J)], B[at(8, J)], B[at(9, J)], B[at(10, J)], ax)
    return R, ax, rx, ry, rz, ow, ox, oy, oz, B[at(11, J)]


@njit(**INLINE)
def link_state(p, B, J):
    """Link J's previous deformation (the eight values of ``physics.link_frame``'s d; row 3
    of the state, the first end's x rotation, stays 0) and its constants
    (``physics.link_response``), read once its frame is computed (values live across the
    frame's arithmetic take vector registers: ``keep_deformation``)."""
    S = ROW_STATE
    previous = (B[at(S, J)], B[at(S + 1, J)], B[at(S + 2, J)], B[at(S + 4, J)],
                B[at(S + 5, J)], B[at(S + 6, J)], B[at(S + 7, J)], B[at(S + 8, J)])
    real = B.dtype.type  # the link's precision: the robot's constants in it
    constants = (B[at(ROW_STIFF, J)], real(p.L), real(p.a1), real(p.a2), real(p.b1),
                 real(p.b2), real(p.b3))
    return previous, constants


@njit(**INLINE)
def keep_deformation(B, J, d):
    """Keep link J's deformation d as its previous one (after that was read: ``link_state``),
    before its loads are computed: d kept live through ``physics.link_response`` instead
    took so many vector registers that LLVM gave the float32 link loop 4 lanes, not 8 (the
    count of ymm instructions in its machine code fell from 277 to 38)."""
    S = ROW_STATE
    B[at(S, J)], B[at(S + 1, J)], B[at(S + 2, J)] = d[0], d[1], d[2]
    B[at(S + 4, J)], B[at(S + 5, J)] = d[3], d[4]
    B[at(S + 6, J)], B[at(S + 7, J)], B[at(S + 8, J)] = d[5], d[6], d[7]


@njit(**INLINE)
def write_loads(B, J, loads):
    """Link J's loads (world axes) into the output rows."""
    O = ROW_OUT
    (B[at(O, J)], B[at(O + 1, J)], B[at(O + 2, J)], B[at(O + 3, J)], B[at(O + 4, J)],
     B[at(O + 5, J)], B[at(O + 6, J)], B[at(O + 7, J)], B[at(O + 8, J)]) = loads


@njit(**INLINE)
def link_step(p, B, J, small, damp):
    """Link J in the frame ``small`` names (a constant in each of ``link_kernel``'s loops):
    ``physics.link_frame``, then ``physics.link_response`` with bond damping damp. Returns
    the divergence flag and whether the link changes frame."""
    R, ax, rx, ry, rz, ow, ox, oy, oz, rest = link_inputs(B, J)
    W, d, change = link_frame(small, R, ax, rx, ry, rz, ow, ox, oy, oz, rest)
    previous, constants = link_state(p, B, J)
    keep_deformation(B, J, d)
    loads, bad = link_response(damp, W, d, previous, rest, constants)
    write_loads(B, J, loads)
    return bad, change


@njit(**INLINE)
def link_reframe(p, B, J, small):
    """Link J, which has outgrown the frame ``small``, computed again in the other
    (``physics.reframe``: undamped, then flipped). Returns the divergence flag."""
    R, ax, rx, ry, rz, ow, ox, oy, oz, rest = link_inputs(B, J)
    W, d, damp, mode = reframe(small, R, ax, rx, ry, rz, ow, ox, oy, oz, rest)
    previous, constants = link_state(p, B, J)
    keep_deformation(B, J, d)
    loads, bad = link_response(damp, W, d, previous, rest, constants)
    write_loads(B, J, loads)
    B[at(ROW_MODE, J)] = mode
    return bad


@njit(**JIT)
def swap_links(a, b, B, ends, vlink, link_id):
    """Exchange the places of links a and b: their rows in the buffer (all but the inputs,
    which the next gather rewrites), their voxels, ids, and the voxel faces that name them."""
    m = len(link_id)
    A, C = place(a), place(b)
    for row in range(ROW_STATE, LINK_ROWS):
        x, y = at(row, A), at(row, C)
        B[x], B[y] = B[y], B[x]
    for e in (0, m):
        ends[e + a], ends[e + b] = ends[e + b], ends[e + a]
    link_id[a], link_id[b] = link_id[b], link_id[a]
    for s in (a, b):
        ax = int(B[at(ROW_AXIS, place(s))])
        vlink[ends[s], 2 * ax + 1] = place(s)
        vlink[ends[m + s], 2 * ax] = place(s)


@njit(**JIT)
def change_frames(p, B, ends, vlink, link_id, split, moved):
    """Links that a frame loop marked LEAVES or RETURNS, computed again in their new frame
    (``link_reframe``: undamped, their previous deformation was measured in the other frame),
    then moved into that frame's run; ``split`` gets the new boundary; ``moved`` (m places) is scratch.
    Returns how many of them diverged.

    The marked links are found block by block (a vectorized count per block of
    CHANGE_BLOCK places of a tile, then a scan of the blocks that hold any), so a step in
    which a few links change frame costs little more than one that has none."""
    m = len(link_id)
    ns = split[0]
    count = 0  # moved[:count]: leavers (ascending), then returners (ascending)
    bad = 0
    for first in range(0, m, LINK_TILE):
        tile = place(first)
        for lo in range(0, min(LINK_TILE, m - first), CHANGE_BLOCK):
            hi = min(lo + CHANGE_BLOCK, m - first)
            marked = 0
            for lane in range(lo, hi):
                marked += 1 if abs(B[at(ROW_MODE, tile + np.uint64(lane))]) > 1.5 else 0
            if marked == 0:
                continue
            for lane in range(lo, hi):
                J = tile + np.uint64(lane)
                mode = B[at(ROW_MODE, J)]
                if mode != LEAVES and mode != RETURNS:
                    continue
                bad += link_reframe(p, B, J, mode == LEAVES)
                moved[count] = first + lane
                count += 1
    # leavers (all below ns), from the highest down, to the top of the small run; then
    # returners (all at ns or above), from the lowest up, to the bottom of the large run
    leavers = 0
    while leavers < count and moved[leavers] < ns:
        leavers += 1
    for q in range(leavers - 1, -1, -1):
        ns -= 1
        if moved[q] != ns:
            swap_links(moved[q], ns, B, ends, vlink, link_id)
    for q in range(leavers, count):
        if moved[q] != ns:
            swap_links(moved[q], ns, B, ends, vlink, link_id)
        ns += 1
    split[0] = ns
    return bad


@njit(**JIT)
def link_kernel(p, ends, split, pos, quat, size, B):
    """Beam forces of every link, in world axes, into the output rows of the link buffer B.
    Returns how many links diverged (|elongation| > MAX_STRAIN * rest length, or NaN) and how
    many changed frame (marked LEAVES or RETURNS, for ``change_frames``).

    Co-rotational: the frame follows the negative-side voxel while the bend is small
    (``physics.small_frame``) and the centre-to-centre line when it is large
    (``physics.large_frame``), with hysteresis as Voxelyze (``physics.link_frame``'s change,
    ``physics.reframe``). Bond damping is stiffness-proportional: the beam sees
    d + damp_j (change of d per step), damp_j = gamma_link / (2 dt), which gives every beam
    term the damping coefficient 2 zeta sqrt(m_link k); a link with no previous step in its
    frame (the first step, or just changed frame) is not damped. Link j's beam constants are
    ``p.a1`` ... times its stiffness scale E_link / E_ref.

    The links are stored in two runs: places [0, split[0]) in the small-angle frame, the rest
    in the large one. Each run is, per tile, one loop over contiguous lanes with no branch,
    which LLVM compiles to SIMD, and computes only its own frame (the small one is about half
    the work of the large). ``ends`` holds the links' negative voxels, then their positive
    ones, by place. A voxel's force and moment do not depend on where its links are stored
    (``link_sums`` sums them by face).
    """
    wide_vectors()
    m = len(ends) // 2
    U = np.uint64
    # gather: the one loop with indirect access, on flat views with unsigned offsets (no
    # negative-index wrap-around to test per load); components are rows (``State``)
    Q, P, n = quat.reshape(-1), pos.reshape(-1), U(pos.shape[1])
    for first in range(0, m, LINK_TILE):
        tile = place(first)
        for lane in range(min(LINK_TILE, m - first)):
            J, j = tile + U(lane), first + lane
            i, k = U(ends[j]), U(ends[m + j])
            B[at(0, J)], B[at(1, J)] = Q[i], Q[n + i]
            B[at(2, J)], B[at(3, J)] = Q[U(2) * n + i], Q[U(3) * n + i]
            B[at(4, J)], B[at(5, J)] = Q[k], Q[n + k]
            B[at(6, J)], B[at(7, J)] = Q[U(2) * n + k], Q[U(3) * n + k]
            B[at(8, J)] = P[k] - P[i]
            B[at(9, J)] = P[n + k] - P[n + i]
            B[at(10, J)] = P[U(2) * n + k] - P[U(2) * n + i]
            B[at(11, J)] = rest_length(size[i], size[k])
    ns = split[0]
    count = 0  # diverged links plus MOVED times the links that change frame (one reduction)
    # each run tile by tile: one SIMD loop over the run's lanes [lo, hi) of each tile
    for first in range(0, m, LINK_TILE):
        tile = place(first)
        lo, hi = 0, max(0, min(LINK_TILE, ns - first))
        for lane in range(lo, hi):  # mode +1, or 0 before the first step (nothing to damp)
            J = tile + U(lane)
            damp = frame_damping(B[at(ROW_MODE, J)], B[at(ROW_DAMP, J)])
            flag, leave = link_step(p, B, J, True, damp)
            B[at(ROW_MODE, J)] = LEAVES if leave else 1.0
            count += MOVED if leave else flag
        lo, hi = hi, min(LINK_TILE, m - first)
        for lane in range(lo, hi):  # mode -1
            J = tile + U(lane)
            flag, enter = link_step(p, B, J, False, B[at(ROW_DAMP, J)])
            B[at(ROW_MODE, J)] = RETURNS if enter else -1.0
            count += MOVED if enter else flag
    return count % MOVED, count // MOVED


@njit(**JIT)
def link_sums(vlink, B, force, moment):
    """Force and moment on every voxel from its links (overwrites ``force``/``moment``: (3, n),
    rows by component).

    ``vlink[v, 2a + 1]`` is the offset (``place``) of the link on v's +a face (v its negative
    end), ``vlink[v, 2a]`` of the one on its -a face (v its positive end); a face without a
    link holds that of place m, which stays zero in every row of the link buffer B, so every
    voxel sums six entries per row without a branch (``physics.voxel_loads``).
    """
    U = np.uint64
    for v in range(len(vlink)):
        (force[0, v], force[1, v], force[2, v],
         moment[0, v], moment[1, v], moment[2, v]) = voxel_loads(
            face_loads(B, U(vlink[v, 1])), face_loads(B, U(vlink[v, 3])),
            face_loads(B, U(vlink[v, 5])), face_loads(B, U(vlink[v, 0])),
            face_loads(B, U(vlink[v, 2])), face_loads(B, U(vlink[v, 4])))


@njit(**INLINE)
def face_loads(B, J):
    """The nine loads of the link at offset J (``place``) in float64 (``physics.voxel_loads``;
    the sums are float64 in either precision, so that a link's equal and opposite forces
    still cancel in the total)."""
    F, O = np.float64, ROW_OUT
    return (F(B[at(O, J)]), F(B[at(O + 1, J)]), F(B[at(O + 2, J)]), F(B[at(O + 3, J)]),
            F(B[at(O + 4, J)]), F(B[at(O + 5, J)]), F(B[at(O + 6, J)]), F(B[at(O + 7, J)]),
            F(B[at(O + 8, J)]))


# ---------------------------------------------------------------- self-collisions
@njit(**JIT)
def collision_pairs(surface, pos, near, reach, pairs, partners):
    """Candidate pairs of surface voxels closer than ``reach`` (sweep along x) that ``near``
    does not list for each other (its rows: the voxels a voxel never touches, -1 pads; the
    face neighbours ``nbr`` for bonded pairs only; ``substeps.is_candidate``), into ``pairs``;
    returns how many, or -1 if a voxel has more than MAX_CONTACTS candidates (the contact
    policy: ``sim.physics``; ``pairs`` holds surface * MAX_CONTACTS / 2 of them).
    ``partners`` (n voxels): scratch, each voxel's count."""
    ns = len(surface)
    xs = np.empty(ns)
    for a in range(ns):
        xs[a] = pos[0, surface[a]]
        partners[surface[a]] = 0
    order = np.argsort(xs)
    # the sweep reads the surface in x order from contiguous copies (no gathers in its loop)
    ids, sx, sy, sz = np.empty(ns, np.int64), np.empty(ns), np.empty(ns), np.empty(ns)
    for a in range(ns):
        v = surface[order[a]]
        ids[a], sx[a], sy[a], sz[a] = v, pos[0, v], pos[1, v], pos[2, v]
    count = 0
    reach2 = reach * reach
    flat, width = near.reshape(-1), near.shape[1]
    for a in range(ns):
        i, x, y, z = ids[a], sx[a], sy[a], sz[a]
        for b in range(a + 1, ns):
            dx = sx[b] - x
            if dx > reach:
                break
            j = ids[b]
            if is_candidate(flat, width, i, j, dx, sy[b] - y, sz[b] - z, reach2):
                partners[i] += 1
                partners[j] += 1
                if partners[i] > MAX_CONTACTS or partners[j] > MAX_CONTACTS:
                    return -1
                pairs[count, 0] = i
                pairs[count, 1] = j
                count += 1
    return count


@njit(**INLINE)
def opposite(out, a, b, x, y, z):
    """A pair's equal and opposite vectors: (x, y, z) added to row a of ``out``, taken from
    row b."""
    out[a, 0] += x
    out[a, 1] += y
    out[a, 2] += z
    out[b, 0] -= x
    out[b, 1] -= y
    out[b, 2] -= z


@njit(**JIT)
def contact_forces_kernel(count, pairs, pos, lin_mom, size, vconst, force, reach=0.5,
                          stiff=1.0, damp=1.0):
    """Penalty contact between voxels of the candidate pairs (``substeps.pair_force``), added
    to ``force`` ((3, n) like ``pos`` and ``lin_mom``: rows by component): equal and
    opposite, so momentum is kept. Contact begins at ``reach`` times the sum of the two sizes
    (0.5: touching cubes); stiffness: ``stiff`` times the harmonic mean of the two voxels'
    2 E L (exactly it for one material); damping: ``damp`` times the mean of their collision
    damping coefficients. The paper's engine: 0.75, 0.5, 0
    (``Params.contact_*``)."""
    P, LM, VC, nc = pos.reshape(-1), lin_mom.reshape(-1), vconst.reshape(-1), vconst.shape[1]
    n, out = pos.shape[1], force.T  # components are rows (``State``)
    for q in range(count):
        i, j = pairs[q, 0], pairs[q, 1]
        touch, fx, fy, fz = pair_force(P, LM, size, VC, nc, i, j, reach, stiff, damp, 1, n)
        if not touch:
            continue
        opposite(out, j, i, fx, fy, fz)


FAR_SURFACE = 1024  # surfaces up to this size list their far pairs (at most 2 MB of them)


@njit(**JIT)
def far_pairs(surface, near, n_voxels, collide):
    """The surface's pairs that ``near`` lists for neither voxel (the only ones that can ever
    be contact candidates; it lists bonded and nearby voxels for each other), by row: row a
    (``far[first[a]:first[a + 1]]``) holds the surface indices b > a of a's pairs, ascending.
    Empty (no rows) without self-collisions or for a surface of more than FAR_SURFACE voxels,
    whose candidates the sweep lists (``collision_pairs``)."""
    ns = len(surface)
    if not collide or ns > FAR_SURFACE:
        return np.zeros(0, np.int64), np.zeros(0, np.int32)
    first = np.zeros(ns + 1, np.int64)
    mark = np.zeros(n_voxels, np.bool_)  # voxels of row a's near list
    far = np.empty(ns * (ns - 1) // 2, np.int32)
    count = 0
    for a in range(ns):
        i = surface[a]
        for w in near[i]:
            if w >= 0:
                mark[w] = True
        for b in range(a + 1, ns):
            if not mark[surface[b]]:
                far[count] = b
                count += 1
        for w in near[i]:
            if w >= 0:
                mark[w] = False
        first[a + 1] = count
    return first, far[:count].copy()


# The far pairs within the candidate radius plus OUTER_MARGIN voxel lengths are kept in an
# outer list, rebuilt only once the surface has spread by half of that since it was listed:
# until then it holds every pair within the candidate radius (``outer_pairs``), and the
# candidate list is rebuilt from it instead of from all the far pairs.
OUTER_MARGIN = 1.2


@njit(**INLINE)
def outer_stale(spread, L):
    """Whether the outer list may miss a pair within the candidate radius: half the spread of
    the surface's displacements since it was listed (``surface_moved``) has reached half its
    margin (NaN: never listed)."""
    return not (2.0 * spread < OUTER_MARGIN * L)


@njit(**JIT)
def surface_columns(surface, pos, spos):
    """The surface voxels' positions by component into ``spos`` (3, s): contiguous rows."""
    for a in range(len(surface)):
        v = surface[a]
        spos[0, a], spos[1, a], spos[2, a] = pos[0, v], pos[1, v], pos[2, v]


@njit(**JIT)
def outer_pairs(first, far, spos, radius, outer):
    """The far pairs (``far_pairs``) nearer than ``radius`` (positions ``spos``) into
    ``outer`` (rows a, b: surface indices), in row order; returns how many. Each pair is
    written and the count advanced by whether it is near: no branch on positions."""
    U = np.uint64  # unsigned offsets: no negative-index wrap-around to test per access
    sx, sy, sz = spos[0], spos[1], spos[2]
    out_a, out_b = outer[0], outer[1]
    r2 = radius * radius
    near_ones = U(0)
    for a in range(len(first) - 1):
        x, y, z = sx[a], sy[a], sz[a]
        for q in range(first[a], first[a + 1]):
            b = U(far[q])
            dx, dy, dz = sx[b] - x, sy[b] - y, sz[b] - z
            out_a[near_ones], out_b[near_ones] = a, b  # near_ones <= q: in bounds
            near_ones += U(1) if dx * dx + dy * dy + dz * dz < r2 else U(0)
    return np.int64(near_ones)


@njit(**JIT)
def far_candidates(surface, outer, n_outer, spos, reach, pairs, partners):
    """``collision_pairs`` from the outer list (``outer_pairs``, valid while not
    ``outer_stale``): the same pairs, those nearer than ``reach``, in the same order
    (``sweep_order``); returns how many, or -1 past the policy's cap. No search of ``near``
    (the far pairs are the ones it never lists)."""
    sx, sy, sz = spos[0], spos[1], spos[2]
    for a in range(len(surface)):
        partners[surface[a]] = 0
    reach2 = reach * reach
    count = 0
    for q in range(n_outer):  # a branch per pair: a third of them or fewer are near
        a, b = outer[0, q], outer[1, q]
        dx, dy, dz = sx[b] - sx[a], sy[b] - sy[a], sz[b] - sz[a]
        if dx * dx + dy * dy + dz * dz < reach2:
            i, j = surface[a], surface[b]
            partners[i] += 1
            partners[j] += 1
            if partners[i] > MAX_CONTACTS or partners[j] > MAX_CONTACTS:
                return -1
            pairs[count, 0] = a  # surface indices until ``sweep_order``
            pairs[count, 1] = b
            count += 1
    sweep_order(surface, sx, pairs, count)
    return count


@njit(**JIT)
def sweep_order(surface, sx, pairs, count):
    """The ``count`` candidate pairs of surface indices at the head of ``pairs`` as voxel
    pairs in ``collision_pairs``' order: by the first voxel's place in the surface sorted by
    x (``np.argsort`` of the same values, ``sx``), then the second's, the first the one placed
    lower. The same list, pair for pair, so the contact forces are summed in the same order
    as before (bit-identical runs)."""
    if count == 1:  # one pair has no order; which end comes first does not change a bit
        pairs[0, 0], pairs[0, 1] = surface[pairs[0, 0]], surface[pairs[0, 1]]
    if count <= 1:
        return
    ns = len(sx)
    order = np.argsort(sx)  # surface index at each rank
    rank = np.empty(ns, np.int64)
    for k in range(ns):
        rank[order[k]] = k
    # the pairs by (lower rank, higher rank): a stable counting sort by the higher rank, then
    # by the lower (ranks are distinct, so this is the sweep's order whatever the sort)
    lo, hi = np.empty(count, np.int64), np.empty(count, np.int64)
    for q in range(count):
        ra, rb = rank[pairs[q, 0]], rank[pairs[q, 1]]
        lo[q], hi[q] = min(ra, rb), max(ra, rb)
    by_hi = counting_order(hi, ns, np.arange(count))
    by_key = counting_order(lo, ns, by_hi)
    for q in range(count):
        k = by_key[q]
        pairs[q, 0], pairs[q, 1] = surface[order[lo[k]]], surface[order[hi[k]]]


@njit(**JIT)
def counting_order(key, buckets, items):
    """``items`` (indices into ``key``) stably ordered by ``key`` (integers in [0, buckets))."""
    start = np.zeros(buckets + 1, np.int64)
    for k in items:
        start[key[k] + 1] += 1
    for b in range(buckets):
        start[b + 1] += start[b]
    out = np.empty(len(items), np.int64)
    for k in items:
        out[start[key[k]]] = k
        start[key[k]] += 1
    return out


@njit(**JIT)
def surface_moved(surface, pos, built):
    """Half the spread of the surface voxels' displacements from ``built`` (their positions
    when the candidate list was built; ``physics.displacement_spread``): a motion the whole
    surface shares does not count. NaN before the first build (``built`` holds NaN)."""
    lo_x = lo_y = lo_z = math.inf
    hi_x = hi_y = hi_z = -math.inf
    for a in range(len(surface)):
        v = surface[a]
        dx, dy, dz = pos[0, v] - built[a, 0], pos[1, v] - built[a, 1], pos[2, v] - built[a, 2]
        lo_x, hi_x = widen(lo_x, hi_x, dx)
        lo_y, hi_y = widen(lo_y, hi_y, dy)
        lo_z, hi_z = widen(lo_z, hi_z, dz)
    return displacement_spread(lo_x, hi_x, lo_y, hi_y, lo_z, hi_z)


@njit(**JIT)
def contact_list_kernel(p, contacts, surface, near, pos, pairs, partners, built, far_first, far,
                        spos, outer, n_outer, outer_built):
    """The self-contact candidates, rebuilt when they may be stale, if the robot has
    self-collisions; returns the updated ``Contacts`` (``count`` -1: a voxel has more
    candidates than the policy keeps, and the run stops).

    ``contacts.travel`` bounds half the spread of the surface voxels' displacements since the
    candidate list was built (``physics.travel_after``). Once it is stale
    (``physics.contacts_stale``) the spread is measured (``surface_moved``): the list is
    rebuilt only if that is stale too, otherwise the bound restarts from it (a voxel that
    vibrates fast but goes nowhere, or a body that moves as a whole, does not force
    rebuilds)."""
    if not p.collide:
        return contacts
    count, travel = contacts.count, contacts.travel
    if contacts_stale(travel, p.L):
        travel = surface_moved(surface, pos, built)
        if contacts_stale(travel, p.L):  # NaN before the first build
            reach = candidate_radius(p.L, p.contact_reach, p.amp)
            if len(far_first):
                surface_columns(surface, pos, spos)
                if outer_stale(surface_moved(surface, pos, outer_built), p.L):
                    n_outer[0] = outer_pairs(far_first, far, spos, reach + OUTER_MARGIN * p.L, outer)
                    outer_built[:] = spos.T
                count = far_candidates(surface, outer, n_outer[0], spos, reach, pairs, partners)
            else:
                count = collision_pairs(surface, pos, near, reach, pairs, partners)
            for a in range(len(surface)):
                for c in range(3):
                    built[a, c] = pos[c, surface[a]]
            travel = 0.0
    return Contacts(count, travel)


# ---------------------------------------------------------------- drag on the surface mesh
@njit(**JIT)
def mesh_vertices_kernel(mesh_vert, exposed, L, pos, quat, size, vert_pos, corners):
    """The vertices of the deformed surface mesh (``sim.system.surface_mesh``) into
    ``vert_pos``: each the mean over the voxels that share it of the voxel's corner
    (``physics.voxel_corner``: its centre plus its corner, rotated; as in the fork, a corner
    sits half the voxel's current size out along an axis where the voxel has a neighbour on
    that side, and half the nominal size L out where that face is exposed).

    In two loops: every voxel's 8 corners in world axes into ``corners`` (component, corner,
    voxel: one branch-free loop over the voxels, one SIMD lane each); each vertex the mean of
    its voxels' corners, summed in ``mesh_vert``'s order (the same sums, in the same order,
    as the GPU engine's one pass per vertex and voxel). Both on flat views with unsigned
    offsets: on the 3-d arrays the corner loop took about 12 ns a voxel, on them about 9
    (docs/benchmarks.md)."""
    U = np.uint64
    n = U(pos.shape[1])  # components are rows (``State``)
    Q, P, C = quat.reshape(-1), pos.reshape(-1), corners.reshape(-1)
    for v in range(pos.shape[1]):
        V = U(v)
        R = rotation_matrix(Q[V], Q[n + V], Q[U(2) * n + V], Q[U(3) * n + V])
        x, y, z = P[V], P[n + V], P[U(2) * n + V]
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = R
        xm, xp, ym, yp, zm, zp = corner_extents(size[V], L, exposed[V])
        for c in range(8):
            ox, oy, oz = mesh_corner(c, xm, xp, ym, yp, zm, zp)
            o = U(c) * n + V
            C[o], C[U(8) * n + o], C[U(16) * n + o] = corner_point(
                x, y, z, r00, r01, r02, r10, r11, r12, r20, r21, r22, ox, oy, oz)
    M, X = mesh_vert.reshape(-1), vert_pos.reshape(-1)
    for k in range(len(mesh_vert)):
        ax, ay, az, count = 0.0, 0.0, 0.0, 0
        for slot in range(8):
            code = M[U(8) * U(k) + U(slot)]
            if code < 0:
                break
            o = U(code & 7) * n + U(code >> 3)
            ax, ay, az = ax + C[o], ay + C[U(8) * n + o], az + C[U(16) * n + o]
            count += 1
        K = U(3) * U(k)
        X[K], X[K + U(1)], X[K + U(2)] = ax / count, ay / count, az / count


@njit(**JIT)
def mesh_drag_kernel(drag, mesh_face, lin_mom, inv_mass, vert_pos, force):
    """The paper's engine's water drag, added to ``force``: on each triangle of the deformed
    surface mesh (vertices ``vert_pos``: ``mesh_vertices_kernel``) moving into the fluid,
    -``drag`` A (v.n)^2 n, A its area, n its unit normal and v the velocity of the voxel
    whose face it covers (``physics.facet_force``; ``drag`` = 0.5 rho C_d; ``inv_mass``: each
    voxel's 1 / m), added to that voxel's force in triangle order.

    One exposed face at a time: its two triangles are consecutive rows of ``mesh_face`` that
    share their voxel and their first vertex (``system.surface_mesh``), so the voxel's
    momentum and that vertex are read once and the two forces added in one pass (the same
    sums in the same order as one triangle at a time); flat views, unsigned offsets."""
    U = np.uint64
    T, V, LM, F = mesh_face.reshape(-1), vert_pos.reshape(-1), lin_mom.reshape(-1), force.reshape(-1)
    n = U(force.shape[1])  # components are rows (``State``)
    for face in range(len(mesh_face) // 2):
        k = U(8) * U(face)  # rows 2 face and 2 face + 1: (a, b, c, voxel), (a, s, t, voxel)
        a, b, c = U(3) * U(T[k]), U(3) * U(T[k + U(1)]), U(3) * U(T[k + U(2)])
        s, t, v = U(3) * U(T[k + U(5)]), U(3) * U(T[k + U(6)]), U(T[k + U(3)])
        ax, ay, az = V[a], V[a + U(1)], V[a + U(2)]
        px, py, pz, inv_m = LM[v], LM[v + n], LM[v + U(2) * n], inv_mass[v]
        f0 = facet_force_of(drag, ax, ay, az, V[b], V[b + U(1)], V[b + U(2)], V[c],
                            V[c + U(1)], V[c + U(2)], px, py, pz, inv_m)
        f1 = facet_force_of(drag, ax, ay, az, V[s], V[s + U(1)], V[s + U(2)], V[t],
                            V[t + U(1)], V[t + U(2)], px, py, pz, inv_m)
        F[v] = F[v] + f0[0] + f1[0]
        F[v + n] = F[v + n] + f0[1] + f1[1]
        F[v + U(2) * n] = F[v + U(2) * n] + f0[2] + f1[2]


# ---------------------------------------------------------------- voxels
@intrinsic
def bits_of(typingctx, x):
    """The float64 x's bits as an int64: for x >= 0 (or NaN) in the same order as x, so that
    a loop's largest value is an integer maximum, which LLVM vectorizes (a float maximum it
    vectorizes only with 'nnan', which ``FASTMATH`` leaves out)."""
    if x != types.float64:
        return None

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], llvmlite.ir.IntType(64))

    return types.int64(types.float64), codegen


@intrinsic
def float_of(typingctx, b):
    """The float64 whose bits are the int64 b (``bits_of``'s inverse)."""
    if b != types.int64:
        return None

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], llvmlite.ir.DoubleType())

    return types.float64(types.int64), codegen


@njit(**INLINE)
def voxel_pass(world, flags, ext_force, exposed, vcols, pos, quat, lin_mom, ang_mom, size,
               force, moment, static, contact):
    """``voxel_update_kernel``'s pass over the voxels for one ``world`` (its switches
    constants: each caller's loop has only its world's code, and no branch, so LLVM
    vectorizes it). Returns the bits of the largest squared speed (``bits_of``), whether
    every voxel stayed sane and how many turned past the series (``physics.voxel_update``)."""
    U = np.uint64
    n = U(len(flags))
    P, Q, LM, AM = pos.reshape(-1), quat.reshape(-1), lin_mom.reshape(-1), ang_mom.reshape(-1)
    F, M, E, VC = force.reshape(-1), moment.reshape(-1), ext_force.reshape(-1), vcols.reshape(-1)
    X, Y, Z = U(0), n, U(2) * n  # a vector's components: rows (``State``)
    QW, QX, QY, QZ = U(0), n, U(2) * n, U(3) * n  # a quaternion's, stored (w, x, y, z)
    insane = 0  # integer reductions: LLVM vectorizes those
    fastest = 0  # bits of the largest squared speed (>= 0)
    turns = 0
    for v in range(len(flags)):
        c = U(v)  # voxel v: column c of every row
        (x, y, z, qw, qx, qy, qz, px, py, pz, lx, ly, lz, still, touch, v2, sane,
         turn) = voxel_update_of(
            world, (VC[c + U(V_MASS) * n], VC[c + U(V_INV_MASS) * n],
                    VC[c + U(V_INV_INERTIA) * n], VC[c + U(V_CGLIN) * n],
                    VC[c + U(V_CGANG) * n], VC[c + U(V_KFLOOR) * n], VC[c + U(V_CCOLL) * n]),
            exposed[c], size[c], flags[c] & FLAG_FIXED != 0,
            F[c + X] + E[c + X], F[c + Y] + E[c + Y], F[c + Z] + E[c + Z],
            M[c + X], M[c + Y], M[c + Z], P[c + X], P[c + Y], P[c + Z],
            Q[c + QW], Q[c + QX], Q[c + QY], Q[c + QZ], LM[c + X], LM[c + Y], LM[c + Z],
            AM[c + X], AM[c + Y], AM[c + Z], static[c])
        static[c] = still
        contact[c] = touch
        LM[c + X], LM[c + Y], LM[c + Z] = px, py, pz
        P[c + X], P[c + Y], P[c + Z] = x, y, z
        AM[c + X], AM[c + Y], AM[c + Z] = lx, ly, lz
        Q[c + QW], Q[c + QX], Q[c + QY], Q[c + QZ] = qw, qx, qy, qz
        speed_bits = bits_of(v2)
        fastest = speed_bits if speed_bits > fastest else fastest
        insane += 0 if sane else 1
        turns += 1 if turn else 0
    return fastest, insane == 0, turns


@njit(**JIT)
def voxel_update_kernel(p, flags, ext_force, exposed, vcols, pos, quat, lin_mom, ang_mom, size,
                        force, moment, static, contact):
    """Everything that acts on one voxel alone, then its step (each voxel's state is read
    once into locals and written once):

    - world forces: gravity, global damping and, in water, drag, added to the links' and
      collisions' force and moment (each voxel's own mass and damping);
    - on land, a penalty floor at z = 0 with static and kinetic (Coulomb) friction: a static
      voxel starts to slide when the horizontal force exceeds mu_s times the normal force; a
      sliding one feels mu_k times the normal force against its horizontal velocity (the
      paper's engine, ``Params.friction``: a voxel at rest is held while the horizontal force
      is below mu_s N; a moving one stops dead when mu_k N dt would take all its momentum);
    - semi-implicit Euler: momenta first, then position and orientation from the new momenta;
      a sliding voxel in floor contact sticks when friction would reverse it (work-energy), and
      a static one keeps no horizontal momentum.

    Each voxel's update is ``physics.voxel_update``, in one branch-free pass over the voxels
    (``voxel_pass``, one loop per world: land with either friction rule, water, neither),
    which LLVM compiles to SIMD; the few voxels whose rotation is past the series of that
    pass (``physics.voxel_turn``) get their orientation in a second pass, only in the steps
    that have any. Fixed voxels feel nothing and keep zero momenta. ``force``/``moment`` hold
    the link and collision terms (the world forces are added to them in registers);
    ``exposed``: each voxel's exposed faces (bits, for the drag in water:
    ``system.exposed_faces``); ``vcols``: the voxels' constants by column (``Voxels.vcols``);
    ``contact`` marks the voxels on the floor. Returns the largest squared speed of a voxel
    after the step, or -1 if any voxel left the sane range (or went NaN)."""
    dt, g, drag, water, land, mu_s, mu_k, fork, slide = voxel_world(p)
    if land and fork:
        fastest, ok, turns = voxel_pass(
            (dt, g, drag, False, True, mu_s, mu_k, True, slide), flags, ext_force, exposed, vcols,
            pos, quat, lin_mom, ang_mom, size, force, moment, static, contact)
    elif land:
        fastest, ok, turns = voxel_pass(
            (dt, g, drag, False, True, mu_s, mu_k, False, slide), flags, ext_force, exposed, vcols,
            pos, quat, lin_mom, ang_mom, size, force, moment, static, contact)
    elif water:
        fastest, ok, turns = voxel_pass(
            (dt, g, drag, True, False, mu_s, mu_k, False, slide), flags, ext_force, exposed, vcols,
            pos, quat, lin_mom, ang_mom, size, force, moment, static, contact)
    else:
        fastest, ok, turns = voxel_pass(
            (dt, g, drag, False, False, mu_s, mu_k, False, slide), flags, ext_force, exposed, vcols,
            pos, quat, lin_mom, ang_mom, size, force, moment, static, contact)
    if turns:
        inv_inertia = vcols[V_INV_INERTIA]
        for v in range(len(flags)):
            lx, ly, lz = ang_mom[0, v], ang_mom[1, v], ang_mom[2, v]
            step_i = inv_inertia[v] * dt
            if not quat_from_small_rotvec(lx * step_i, ly * step_i, lz * step_i)[4]:
                continue
            quat[0, v], quat[1, v], quat[2, v], quat[3, v], sane = voxel_turn(
                inv_inertia[v], dt, lx, ly, lz, quat[0, v], quat[1, v], quat[2, v], quat[3, v])
            ok = ok and sane
    return float_of(fastest) if ok else -1.0


# ---------------------------------------------------------------- the step
class Voxels(NamedTuple):
    """One robot's per-voxel constants (indices local to the robot)."""

    flags: np.ndarray  # (n,) int8: FLAG_FIXED | FLAG_ACTIVE
    ext_force: np.ndarray  # (3, n) newtons, by component
    cos_phase: np.ndarray  # (n,) cos of the actuation phase
    sin_phase: np.ndarray  # (n,)
    phase: np.ndarray  # (n,) radians
    nbr: np.ndarray  # (n, 6) face neighbours (-1: exposed face)
    exposed: np.ndarray  # (n,) bit f set: face f exposed (``system.exposed_faces``)
    surface: np.ndarray  # (s,) voxels with an exposed face
    vconst: np.ndarray  # (n, N_VCONST) mass, damping, floor stiffness, frequency (V_*)
    vcols: np.ndarray  # (N_VCONST, n) the same by column (``voxel_update_kernel``'s vectors)
    near: np.ndarray  # (n, k) voxels never in contact with each voxel (-1 pads)
    mesh_vert: np.ndarray  # (nv, 8) surface-mesh vertices: 8 voxel + corner (-1 pads)
    mesh_face: np.ndarray  # (nf, 4) surface-mesh triangles: 3 vertices and their voxel


class Links(NamedTuple):
    """One robot's links: the voxels at their ends, their axes, and each voxel's links."""

    neg: np.ndarray  # (m,) voxel on the negative side
    pos: np.ndarray  # (m,) voxel on the positive side
    axis: np.ndarray  # (m,) 0 x, 1 y, 2 z
    vlink: np.ndarray  # (n, 6) link on each face, ordered as nbr (m: none)
    stiff: np.ndarray  # (m,) E_link / E_ref: the scale of the beam constants
    damp: np.ndarray  # (m,) bond damping gamma_link / (2 dt)


class Work(NamedTuple):
    """Scratch and per-link state of one robot's run, overwritten step by step."""

    size: np.ndarray  # (n,) current (actuated) voxel size
    force: np.ndarray  # (3, n) total force on each voxel, by component
    moment: np.ndarray  # (3, n) total moment on each voxel, by component
    static: np.ndarray  # (n,) bool: held by static friction
    pairs: np.ndarray  # (p, 2) self-collision candidates
    partners: np.ndarray  # (n,) candidates of each voxel (``collision_pairs``' scratch)
    contact: np.ndarray  # (n,) bool: touching the floor this step
    built: np.ndarray  # (s, 3) surface voxels' positions when the candidates were listed
    far_first: np.ndarray  # (s + 1,) row starts in ``far`` (empty: the sweep lists candidates)
    far: np.ndarray  # int32 surface pairs ``near`` never lists, by row (``far_pairs``)
    spos: np.ndarray  # (3, s) scratch: the surface's positions by component (``surface_columns``)
    outer: np.ndarray  # (2, len(far)) int32 the far pairs within the outer radius (``outer_pairs``)
    n_outer: np.ndarray  # (1,) how many
    outer_built: np.ndarray  # (s, 3) surface voxels' positions when they were listed (NaN: never)
    # the links as ``link_kernel`` keeps them, in two runs by frame (see there):
    link_buf: np.ndarray  # link_buffer_size(m): inputs, state, output, constants per link
    link_ends: np.ndarray  # (2 m,) negative voxels, then positive voxels
    vlink: np.ndarray  # (n, 6) offset (``place``) of the link on each face (of place m: none)
    link_id: np.ndarray  # (m,) the link (index in ``Links``) at each place
    split: np.ndarray  # (1,) places [0, split) hold the links in the small-angle frame
    changed: np.ndarray  # (m,) scratch of ``change_frames``
    vert_pos: np.ndarray  # (nv, 3) surface-mesh vertex positions (``mesh_vertices_kernel``)
    corners: np.ndarray  # (3, 8, n) every voxel's corners (``mesh_vertices_kernel``; n 0 on land)


class Contacts(NamedTuple):
    """Self-collision candidates carried from step to step."""

    count: int  # pairs in use at the head of ``Work.pairs`` (-1: over the policy's cap)
    travel: float  # bound on any voxel's displacement since the list was built, m


# The sub-steps of ``step``, inlined, named as the GPU engine's (``sim.cuda_kernels``): each
# hands its compiled kernel the arrays it needs one by one and has no branch of its own (those
# live in the kernels). With ``run_robot`` stepping on borrowed views (``borrow``) that leaves
# no reference counting in the step loop.
@njit(**INLINE)
def actuate(t, p, voxels, work):
    """Sizes of the voxels at time t into ``work.size``."""
    actuate_kernel(t, p, voxels.flags, voxels.cos_phase, voxels.sin_phase, voxels.phase,
                   voxels.vconst, work.size)


@njit(**INLINE)
def link_forces(p, links, body, work):
    """Beam forces of every link, summed into each voxel's force and moment (overwritten).
    Returns how many links diverged."""
    bad, moves = link_kernel(p, work.link_ends, work.split, body.pos, body.quat, work.size,
                             work.link_buf)
    if moves:
        bad += change_frames(p, work.link_buf, work.link_ends, work.vlink, work.link_id,
                             work.split, work.changed)
    link_sums(work.vlink, work.link_buf, work.force, work.moment)
    return bad


@njit(**INLINE)
def contact_list(p, voxels, body, work, contacts):
    """The self-contact candidates, rebuilt if stale (``contact_list_kernel``); returns the
    updated ``Contacts``."""
    return contact_list_kernel(p, contacts, voxels.surface, voxels.near, body.pos, work.pairs,
                               work.partners, work.built, work.far_first, work.far, work.spos,
                               work.outer, work.n_outer, work.outer_built)


@njit(**INLINE)
def contact_forces(p, voxels, body, work, contacts):
    """The candidates' contact forces (if on), added to ``work.force``."""
    if p.collide:
        contact_forces_kernel(contacts.count, work.pairs, body.pos, body.lin_mom, work.size,
                              voxels.vconst, work.force, p.contact_reach, p.contact_stiff,
                              p.contact_damp)


@njit(**INLINE)
def mesh_vertices(p, voxels, body, work):
    """The surface mesh's vertices (water with the paper's drag) into ``work.vert_pos``."""
    if p.mesh_drag > 0.0:
        mesh_vertices_kernel(voxels.mesh_vert, voxels.exposed, p.L, body.pos, body.quat,
                             work.size, work.vert_pos, work.corners)


@njit(**INLINE)
def mesh_drag(p, voxels, body, work):
    """The drag on the surface mesh's triangles (if on), added to ``work.force``."""
    if p.mesh_drag > 0.0:
        mesh_drag_kernel(p.mesh_drag, voxels.mesh_face, body.lin_mom, voxels.vcols[V_INV_MASS],
                         work.vert_pos, work.force)


@njit(**INLINE)
def voxel_update(p, voxels, body, work):
    """World forces, floor contact and the Euler step of every voxel (``voxel_update_kernel``);
    returns the largest squared speed or -1."""
    return voxel_update_kernel(p, voxels.flags, voxels.ext_force, voxels.exposed,
                               voxels.vcols, body.pos, body.quat, body.lin_mom, body.ang_mom,
                               work.size, work.force, work.moment, work.static, work.contact)


@njit(**INLINE)
def step(t, p, voxels, links, body, work, contacts):
    """One step of ``p.dt`` of one robot, its body state updated in place; t is the time
    since actuation started (negative before it starts: ``Params.act_start``). Returns how
    many links diverged, the largest squared voxel speed after the step (-1: a voxel left
    the sane range) and the updated ``Contacts``."""
    actuate(t, p, voxels, work)
    bad = link_forces(p, links, body, work)
    contacts = contact_list(p, voxels, body, work, contacts)
    contact_forces(p, voxels, body, work, contacts)
    mesh_vertices(p, voxels, body, work)
    mesh_drag(p, voxels, body, work)
    speed2 = voxel_update(p, voxels, body, work)
    return bad, speed2, Contacts(contacts.count, travel_after(contacts.travel, speed2, p.dt))


# ---------------------------------------------------------------- the rollout
@intrinsic
def borrow(typingctx, arrays):
    """The same tuple of arrays as views that own no memory, so that passing them on and
    taking them out of the tuple costs no reference counting (two atomic updates per array
    and use otherwise: passed to the sub-steps, those took most of a small robot's step).
    The owner must keep the memory alive for as long as the views are used."""
    if not (isinstance(arrays, types.BaseTuple)
            and all(isinstance(t, types.Array) for t in arrays.types)):
        return None

    def codegen(context, builder, signature, args):
        out = args[0]
        for i, ty in enumerate(arrays.types):
            view = context.make_array(ty)(context, builder, value=builder.extract_value(out, i))
            view.meminfo = cgutils.get_null_value(view.meminfo.type)
            view.parent = cgutils.get_null_value(view.parent.type)
            out = builder.insert_value(out, view._getvalue(), i)
        return out

    return arrays(arrays), codegen


@njit(**JIT)
def keep(owners):
    """Nothing: a use of ``owners`` that keeps their memory alive up to this call."""
    return len(owners)


params = njit(**JIT)(params_of)  # a robot's ``Params`` from its rows (``system.params_of``)


@njit(**JIT)
def take_robot(batch, state, r):
    """Private copies of robot r's parameters, voxels, links and body state; the body state
    and the external forces by component, one row each (``State``'s (3, n) and (4, n): the
    voxel update's vector loop reads and writes contiguous rows)."""
    v0, v1 = batch.voff[r], batch.voff[r + 1]
    l0, l1 = batch.loff[r], batch.loff[r + 1]
    s0, s1 = batch.soff[r], batch.soff[r + 1]
    voxels = Voxels(batch.flags[v0:v1].copy(), np.ascontiguousarray(batch.ext_force[v0:v1].T),
                    batch.cos_phase[v0:v1].copy(), batch.sin_phase[v0:v1].copy(),
                    batch.phase[v0:v1].copy(), batch.nbr[v0:v1].copy(),
                    batch.exposed[v0:v1].copy(), batch.surface[s0:s1].copy(), batch.vconst[v0:v1].copy(),
                    np.ascontiguousarray(batch.vconst[v0:v1].T),
                    batch.near[v0:v1].copy(),
                    batch.mesh_vert[batch.moff[r]:batch.moff[r + 1]].copy(),
                    batch.mesh_face[batch.foff[r]:batch.foff[r + 1]].copy())
    links = Links(batch.link_neg[l0:l1].copy(), batch.link_pos[l0:l1].copy(),
                  batch.link_axis[l0:l1].copy(), batch.vlink[v0:v1].copy(),
                  batch.link_stiff[l0:l1].copy(), batch.link_damp[l0:l1].copy())
    body = State(np.ascontiguousarray(state.pos[v0:v1].T),
                 np.ascontiguousarray(state.quat[v0:v1].T),
                 np.ascontiguousarray(state.lin_mom[v0:v1].T),
                 np.ascontiguousarray(state.ang_mom[v0:v1].T))
    return params(batch.fparams[r], batch.iparams[r]), voxels, links, body


@njit(**JIT)
def robot_work(n_voxels, links, n_pairs, surface, near, collide, n_vert, real):
    """``Work`` of one robot's run: static friction flags set, every link in the small-angle
    run at its own place with frame mode 0 (nothing to damp against yet), no candidate list
    built yet (NaN positions), the surface's pairs that can ever be candidates listed
    (``far_pairs``; if ``collide``), everything else zero. The link buffer has ``real``'s
    dtype (an empty array: float64, or float32 for the mixed precision)."""
    n_surface = len(surface)
    far_first, far = far_pairs(surface, near, n_voxels, collide)
    m = len(links.neg)
    buf = np.zeros(link_buffer_size(m), real.dtype)
    for j in range(m):
        J = place(j)
        buf[at(ROW_AXIS, J)], buf[at(ROW_STIFF, J)] = links.axis[j], links.stiff[j]
        buf[at(ROW_DAMP, J)] = links.damp[j]
    vlink = np.empty_like(links.vlink)
    for v in range(len(vlink)):
        for f in range(6):
            vlink[v, f] = place(links.vlink[v, f])
    return Work(np.zeros(n_voxels), np.zeros((3, n_voxels)), np.zeros((3, n_voxels)),
                np.ones(n_voxels, dtype=np.bool_), np.zeros((n_pairs, 2), dtype=np.int64),
                np.zeros(n_voxels, dtype=np.int64), np.zeros(n_voxels, dtype=np.bool_),
                np.full((n_surface, 3), np.nan), far_first, far,
                np.zeros((3, n_surface if len(far_first) else 0)),
                np.zeros((2, len(far)), np.int32), np.zeros(1, np.int64),
                np.full((n_surface if len(far_first) else 0, 3), np.nan), buf,
                np.concatenate((links.neg, links.pos)), vlink, np.arange(m),
                np.full(1, m), np.empty(m, dtype=np.int64), np.zeros((n_vert, 3)),
                np.zeros((3, 8, n_voxels if n_vert else 0)))


@njit(**JIT)
def com(pos, vconst, out, row):
    """Centre of mass into out[row, 1:4] (``physics.centre_of_mass``)."""
    out[row, 1], out[row, 2], out[row, 3] = centre_of_mass(
        pos.shape[1], vconst.reshape(-1), vconst.shape[1], V_WEIGHT, pos.reshape(-1), 1,
        pos.shape[1])


@njit(**INLINE)
def sample(k, p, v0, pos, vconst, frames, traj, n_com):
    """Frames and centre-of-mass samples due at step k (``physics.frame_due``,
    ``physics.com_due``): the robot's positions into ``frames`` (its voxels from v0), its
    centre of mass into ``traj``. Returns the samples taken so far."""
    if frame_due(k, p):
        f = k // p.record
        for v in range(pos.shape[1]):
            for c in range(3):
                frames[f, v0 + v, c] = pos[c, v]
    if com_due(k, p, n_com, traj.shape[0]):
        traj[n_com, 0] = k * p.dt
        com(pos, vconst, traj, n_com)
        n_com += 1
    return n_com


@njit(**JIT)
def run_robot(r, batch, state, frames, com_traj, com_count, status, steps_done, real):
    """Run robot r of the batch to its step count or to divergence, recording frames and
    centre-of-mass samples.

    The robot runs on private copies of its arrays, written back at the end: robots of one
    batch share arrays, and threads writing neighbouring entries of one array every step
    (and updating its reference count on every call) slow each other down several-fold.
    """
    p, own_voxels, own_links, own_body = take_robot(batch, state, r)
    v0, v1 = batch.voff[r], batch.voff[r + 1]
    n = v1 - v0
    own_work = robot_work(n, own_links, batch.poff[r + 1] - batch.poff[r], own_voxels.surface,
                          own_voxels.near, p.collide, len(own_voxels.mesh_vert), real)
    # the steps run on views: no reference counting per step (the owners live to the end)
    voxels, links = borrow(own_voxels), borrow(own_links)
    body, work = borrow(own_body), borrow(own_work)
    traj = np.zeros((com_traj.shape[1], 4))
    contacts = Contacts(0, COLLIDE_MARGIN * p.L)  # as if the margin was closed: build the list
    n_com = 0
    code = STATUS_OK
    done = p.steps
    for k in range(p.steps + 1):
        n_com = sample(k, p, v0, body.pos, voxels.vconst, frames, traj, n_com)
        if k == p.steps:
            break
        bad, speed2, contacts = step((k - p.act_start) * p.dt, p, voxels, links, body, work,
                                     contacts)
        code = step_status(bad != 0, speed2 < 0.0, contacts.count < 0)
        if code != STATUS_OK:
            done = k + 1
            break
    # always keep the final centre of mass as the last sample
    traj[n_com, 0] = done * p.dt
    com(body.pos, voxels.vconst, traj, n_com)
    com_traj[r, : n_com + 1] = traj[: n_com + 1]
    com_count[r] = n_com + 1
    status[r], steps_done[r] = code, done
    state.pos[v0:v1], state.quat[v0:v1] = own_body.pos.T, own_body.quat.T
    state.lin_mom[v0:v1], state.ang_mom[v0:v1] = own_body.lin_mom.T, own_body.ang_mom.T
    keep((own_voxels, own_links, own_body, own_work))


@njit(parallel=True, **JIT)
def run_batch(batch, state, frames, com_traj, com_count, status, steps_done, real):
    """Run every robot of the batch, one robot per parallel task, their links in ``real``'s
    dtype (an empty float64 array, or float32 for the mixed precision: ``robot_work``)."""
    for r in prange(len(batch.voff) - 1):
        run_robot(r, batch, state, frames, com_traj, com_count, status, steps_done, real)
