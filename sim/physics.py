"""The physics of one step, written once, as scalar functions of scalars.

Every piece of the model that acts on one thing at a time is here, and every per-element
body of the step that both engines run: the quaternion helpers; the actuation (its mode for
the step, ``actuation``, and a voxel's size, ``voxel_size``); one link's step (its geometry,
its co-rotational frame, ``link_frame``, the hysteresis transition to the other,
``reframe``, bond damping and the loads in world axes, ``link_response``; its rest length);
one voxel's sum of its links' loads (``voxel_loads``); the self-contact policy
(``candidate_radius``, MAX_CONTACTS, the rebuild trigger ``contacts_stale`` and the travel
bound ``travel_after``, the range of the displacements ``widen``) and one self-contact pair; the
drag on one exposed face or one surface-mesh facet (``facet_normal``, ``facet_force``) and
one corner of the mesh (``voxel_corner``); one voxel's update (world forces, floor contact
and friction, semi-implicit Euler); the run around the steps (``frame_due``, ``com_due``,
``step_status``: the failures in the order both engines check them). The functions take and
return numbers and tuples of numbers only, never arrays (``centre_of_mass``, sampled every
few hundred steps, reads the flat position array; the pieces that index a robot's arrays
are ``sim.substeps``), so that each target compiles them into its own loops and memory
layout:

- ``sim.kernels`` (the CPU engine): ``compiled(njit(inline="always", ...), fma)``, inlined
  into its loops over voxels and links;
- ``sim.cuda_kernels`` (the GPU engine): ``compiled(cuda.jit(device=True, ...), cuda.fma)``,
  device functions called by the threads of a robot's block; on numba-cuda's simulator
  (``NUMBA_ENABLE_CUDASIM=1``) the plain functions below.

``compiled(jit, fma)`` gives each target its own copies (``bind``), which call one another and
that target's ``fma`` (a * b + c with one rounding: LLVM's ``llvm.fma`` on the CPU, the CUDA
intrinsic on the GPU). The equations are those of docs/physics.md; the symbols follow
``sim.kernels``' docstring. Quaternions are (w, x, y, z); a link's frame has x along the link.
"""

from __future__ import annotations

import math
import types
from types import SimpleNamespace

from .system import (  # noqa: F401 (MAX_CONTACTS: the policy below)
    ENV_LAND,
    ENV_WATER,
    FRICTION_VOXCAD,
    MAX_CONTACTS,
    STATUS_CONTACTS,
    STATUS_NONFINITE,
    STATUS_OK,
    STATUS_STRAIN,
)

MAX_STRAIN = 100.0  # axial strain of a link beyond which the run is declared diverged
POSITION_BOUND = 1.0e4  # metres: anything beyond is a blow-up (also catches NaN)
SMALL_TURN, SMALL_EXTEND, HYSTERESIS = 0.05, 0.5, 1.2  # the co-rotational frames' bounds
MIN_SIZE = 0.1  # smallest actuated size, as a fraction of the voxel size
FRICTION_EPS = 1e-9  # horizontal speeds below this many voxel lengths per step count as 0
# The self-contact policy, both engines: candidates are unbonded surface pairs within the
# largest contact distance plus COLLIDE_MARGIN voxel lengths (``candidate_radius``); the list
# is rebuilt once the surface voxels' displacements since it was built spread over the margin
# (``displacement_spread``: what they share, a walk or a swim, does not count). A voxel keeps
# at most MAX_CONTACTS candidates (``sim.system``, which sizes the lists): a run in which one
# has more stops, its ``Result.reason`` says so (no contact is dropped silently). In a solid
# body at the largest amplitude (0.9) a voxel has 60 voxel centres within the radius and
# beyond the paper's collision horizon (3 bonds; 26 beyond 1 bond in voxelyze-2's contact
# model), as with a 0.2 L margin; with 0.3 L the fork's legged and swimming samples run 8-10%
# faster (fewer rebuilds; issue 47), and 0.4 L would put 84 there.
COLLIDE_MARGIN = 0.3


def fma(a, b, c):
    """a * b + c; each target binds its own one-rounding version (``compiled``)."""
    return a * b + c


# ---------------------------------------------------------------- quaternion helpers
def dot3(ax, ay, az, bx, by, bz):
    """a . b with fused multiply-adds."""
    return fma(ax, bx, fma(ay, by, az * bz))


def qmul(aw, ax, ay, az, bw, bx, by, bz):
    """Hamilton product a * b."""
    return (
        fma(aw, bw, -fma(ax, bx, fma(ay, by, az * bz))),
        fma(aw, bx, fma(ax, bw, fma(ay, bz, -(az * by)))),
        fma(aw, by, fma(ay, bw, fma(az, bx, -(ax * bz)))),
        fma(aw, bz, fma(ax, by, fma(az, bw, -(ay * bx)))),
    )


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


# f(u) = 2 acos(1 - u) / sqrt(1 - (1 - u)^2) over u in [0, 1]: a unit quaternion's rotation
# vector is f(1 - |w|) times its vector part. Degree-16 polynomial from a Chebyshev fit to the
# exact function (relative error < 5e-14 everywhere; its nearest singularity is u = 2), so
# rotation vectors need no division, no libm call and no branch, and the link loop vectorizes.
ANGLE_OVER_SIN = (
    2.000000000000085,
    0.666666666619135,
    0.26666667113455084,
    0.11428554822756917,
    0.05079689174055483,
    0.023049764284205198,
    0.010952681225704275,
    0.0033813071236987804,
    0.008445614662157971,
    -0.015982869178300427,
    0.03578579361845359,
    -0.053358252114567725,
    0.05957216182258554,
    -0.0468218000572629,
    0.025036407949616243,
    -0.008136146214563936,
    0.0012522127460549246,
)


def angle_over_sin(u):
    """``ANGLE_OVER_SIN`` at u, by Estrin's scheme (short dependency chains)."""
    c = ANGLE_OVER_SIN
    u2 = u * u
    u4 = u2 * u2
    u8 = u4 * u4
    lo = fma(u4, fma(u2, fma(c[7], u, c[6]), fma(c[5], u, c[4])),
             fma(u2, fma(c[3], u, c[2]), fma(c[1], u, c[0])))
    hi = fma(u4, fma(u2, fma(c[15], u, c[14]), fma(c[13], u, c[12])),
             fma(u2, fma(c[11], u, c[10]), fma(c[9], u, c[8])))
    return fma(u8, fma(u8, c[16], hi), lo)


def rotvec(w, x, y, z):
    """Rotation vector (axis * angle) of a unit quaternion; q and -q give the same one."""
    f = math.copysign(angle_over_sin(1.0 - abs(w)), w)
    return f * x, f * y, f * z


def qmul_x0(aw, ay, az, bw, bx, by, bz):
    """``qmul`` of a = (aw, 0, ay, az) and b, without the products with a's zero."""
    return (
        fma(aw, bw, -fma(ay, by, az * bz)),
        fma(aw, bx, fma(ay, bz, -(az * by))),
        fma(aw, by, fma(ay, bw, az * bx)),
        fma(aw, bz, fma(az, bw, -(ay * bx))),
    )


def rotvec_x0(w, y, z):
    """The y and z parts of ``rotvec`` of the unit quaternion (w, 0, y, z) (its x part is 0)."""
    f = math.copysign(angle_over_sin(1.0 - abs(w)), w)
    return f * y, f * z


def quat_from_rotvec(px, py, pz):
    """Unit quaternion of the rotation vector p (series when the angle is small)."""
    c, qx, qy, qz, turn = quat_from_small_rotvec(px, py, pz)
    if turn:
        return quat_from_large_rotvec(px, py, pz)
    return c, qx, qy, qz


def quat_from_small_rotvec(px, py, pz):
    """``quat_from_rotvec``'s series, without a branch (vector loops take it), and whether the
    angle is too large for it (then ``quat_from_large_rotvec`` gives the quaternion)."""
    a2 = 0.25 * dot3(px, py, pz, px, py, pz)  # (half angle)^2
    c = fma(-a2, fma(-a2, 1.0 / 24.0, 0.5), 1.0)
    f = 0.5 * fma(-a2, fma(-a2, 1.0 / 120.0, 1.0 / 6.0), 1.0)
    return c, f * px, f * py, f * pz, not (a2 < 1e-2)


def quat_from_large_rotvec(px, py, pz):
    """Unit quaternion of the rotation vector p, exact (``quat_from_rotvec`` past its series)."""
    a2 = 0.25 * dot3(px, py, pz, px, py, pz)
    h = math.sqrt(a2)
    c = math.cos(h)
    f = math.sin(h) / (2.0 * h)
    return c, f * px, f * py, f * pz


def rotation_matrix(w, x, y, z):
    """Rows of the rotation matrix of the unit quaternion (w, x, y, z): world = R local."""
    return (
        fma(-2.0, fma(y, y, z * z), 1.0), 2.0 * fma(x, y, -(w * z)), 2.0 * fma(x, z, w * y),
        2.0 * fma(x, y, w * z), fma(-2.0, fma(x, x, z * z), 1.0), 2.0 * fma(y, z, -(w * x)),
        2.0 * fma(x, z, -(w * y)), 2.0 * fma(y, z, w * x), fma(-2.0, fma(x, x, y * y), 1.0),
    )


# ---------------------------------------------------------------- actuation
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


def actuated_size(L, amp, w):
    """Size of an active voxel of nominal size L at signal w: L (1 + amp w), at least
    ``MIN_SIZE`` L."""
    return max(L * (1.0 + amp * w), MIN_SIZE * L)


# How a step actuates its voxels (``actuation``): not yet (every voxel at its nominal size),
# each voxel at its own frequency, all at the robot's in a sine (sin(wt + phi) from sin wt
# and cos wt, no libm per voxel), all at the robot's in another waveform.
ACT_REST, ACT_FIELD, ACT_SINE, ACT_WAVE = 0, 1, 2, 3


def actuation(p, t):
    """How the voxels of the robot ``p`` (``Params``) are actuated at time t (t < 0: not yet,
    ``Params.act_start``), one of ACT_*, and sin wt and cos wt of its angular frequency."""
    wt = p.omega * t
    mode = (ACT_REST if t < 0.0 else ACT_FIELD if p.freq_field
            else ACT_SINE if p.wave == 0 else ACT_WAVE)
    return mode, math.sin(wt), math.cos(wt)


def voxel_size(p, mode, t, active, omega, phase, cos_phase, sin_phase, s_wt, c_wt):
    """The current size of a voxel of the robot ``p`` at time t (``actuation``: mode, s_wt,
    c_wt): its nominal size L when it is passive or at rest, else ``actuated_size`` of the
    waveform at its phase angle (omega: its own angular frequency, used with ACT_FIELD)."""
    if mode == ACT_REST or not active:
        return p.L
    if mode == ACT_FIELD:
        w = waveform(p.wave, omega * t + phase)
    elif mode == ACT_SINE:
        w = s_wt * cos_phase + c_wt * sin_phase
    else:
        w = waveform(p.wave, p.omega * t + phase)
    return actuated_size(p.L, p.amp, w)


# ---------------------------------------------------------------- one link
def to_link(axis, x, y, z):
    """Proper rotation taking the world axis ``axis`` (0 x, 1 y, 2 z) onto +x, as selects
    (links of mixed axes share one vector loop)."""
    return (x if axis == 0 else (y if axis == 1 else z),
            y if axis != 1 else -x,
            z if axis != 2 else -x)


def from_link_matrix(axis, R):
    """R (rows) times the inverse axis permutation: world axes from link axes, as selects."""
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = R
    return (r00 if axis == 0 else (r01 if axis == 1 else r02),
            -r00 if axis == 1 else r01, -r00 if axis == 2 else r02,
            r10 if axis == 0 else (r11 if axis == 1 else r12),
            -r10 if axis == 1 else r11, -r10 if axis == 2 else r12,
            r20 if axis == 0 else (r21 if axis == 1 else r22),
            -r20 if axis == 1 else r21, -r20 if axis == 2 else r22)


def beam(ex, ey, ez, e1x, e1y, e1z, e2x, e2y, e2z, a1, a2, b1, b2, b3):
    """3-D frame element (Euler-Bernoulli) in the link frame: the force on the negative end
    (the positive end gets its opposite) and the moments on both ends."""
    fay = b1 * ey - b2 * (e1z + e2z)
    faz = b1 * ez + b2 * (e1y + e2y)
    max_ = a2 * (e2x - e1x)
    may = -b2 * ez - b3 * (2.0 * e1y + e2y)
    maz = b2 * ey - b3 * (2.0 * e1z + e2z)
    mby = -b2 * ez - b3 * (e1y + 2.0 * e2y)
    mbz = b2 * ey - b3 * (e1z + 2.0 * e2z)
    return a1 * ex, fay, faz, max_, may, maz, -max_, mby, mbz


def link_geometry(aw, ax_, ay, az, bw, bx, by, bz, wx, wy, wz, axis):
    """A link's geometry from its voxels' orientations a (negative end) and b and the world
    offset w from a's centre to b's: the rotation matrix R (rows) of a, and the centre offset
    (rx, ry, rz) and relative rotation (ow, ox, oy, oz) of b in the link frame (a's frame
    turned so that the link's axis is +x)."""
    R = rotation_matrix(aw, ax_, ay, az)
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = R
    rx, ry, rz = to_link(axis, dot3(r00, r10, r20, wx, wy, wz), dot3(r01, r11, r21, wx, wy, wz),
                         dot3(r02, r12, r22, wx, wy, wz))
    ow, ox, oy, oz = qmul(aw, -ax_, -ay, -az, bw, bx, by, bz)
    ox, oy, oz = to_link(axis, ox, oy, oz)
    return R, rx, ry, rz, ow, ox, oy, oz


def small_frame(R, axis, rx, ry, rz, ow, ox, oy, oz, rest):
    """The link in its negative voxel's frame: the offset off the axis is shear, the first end
    does not turn and the second turns by the voxels' relative rotation. Returns W (world
    from the beam's frame), the deformation (elongation d, end rotations t1 = (0, t1y, t1z)
    and t2) and whether the bend or the extension has outgrown the frame."""
    t2x, t2y, t2z = rotvec(ow, ox, oy, oz)
    leave = abs(ry) + abs(rz) > SMALL_TURN * rx or abs(rx - rest) > SMALL_EXTEND * rest
    return (from_link_matrix(axis, R), rx - rest, ry, rz, 0.0, 0.0, t2x, t2y, t2z, leave)


def large_frame(R, axis, rx, ry, rz, ow, ox, oy, oz, rest):
    """The link in the frame of its centre line, which c = k (|r| + rx, 0, rz, -ry) with
    k = 1 / sqrt(2 |r| (|r| + rx)) turns onto +x (half-angle identity; a half turn about z
    when r points back): no shear, the bend shows in both end rotations. Returns as
    ``small_frame``, and whether the link is back within the small-angle frame's bounds
    (tighter by HYSTERESIS than those it left)."""
    length = math.sqrt(rx * rx + ry * ry + rz * rz)
    h = length + rx
    back = h > 1e-4 * length
    cw = h if back else 0.0
    cy = rz if back else 0.0
    cz = -ry if back else 1.0
    k = 1.0 / math.sqrt(2.0 * length * h) if back else 1.0
    # products with the unnormalised c run while k is computed
    pw, px, py, pz = qmul_x0(cw, cy, cz, ow, ox, oy, oz)
    cw, cy, cz = cw * k, cy * k, cz * k
    t1y, t1z = rotvec_x0(cw, cy, cz)  # c has no x part, so t1 has none
    t2x, t2y, t2z = rotvec(pw * k, px * k, py * k, pz * k)
    # world from the beam's frame: voxel rotation, axis permutation, conj(c), composed
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = from_link_matrix(axis, R)
    c00 = 1.0 - 2.0 * (cy * cy + cz * cz)
    c01, c02 = 2.0 * cw * cz, -2.0 * cw * cy
    c11, c12 = 1.0 - 2.0 * cz * cz, 2.0 * cy * cz
    c22 = 1.0 - 2.0 * cy * cy
    W = (dot3(m00, m01, m02, c00, -c01, -c02), dot3(m00, m01, m02, c01, c11, c12),
         dot3(m00, m01, m02, c02, c12, c22),
         dot3(m10, m11, m12, c00, -c01, -c02), dot3(m10, m11, m12, c01, c11, c12),
         dot3(m10, m11, m12, c02, c12, c22),
         dot3(m20, m21, m22, c00, -c01, -c02), dot3(m20, m21, m22, c01, c11, c12),
         dot3(m20, m21, m22, c02, c12, c22))
    enter = (abs(ry) + abs(rz) < (SMALL_TURN / HYSTERESIS) * rx
             and abs(rx - rest) < (SMALL_EXTEND / HYSTERESIS) * rest)
    return W, length - rest, 0.0, 0.0, t1y, t1z, t2x, t2y, t2z, enter


def frame_damping(mode, damp):
    """The bond damping of a link in the co-rotational frame it is in (``mode``: +1 small,
    -1 large, 0 before its first step): ``damp``, or none before the first step, when there
    is no previous deformation to damp against. (A link that has just changed frame is
    computed undamped too: its previous deformation was measured in the other frame.) The
    frames' bounds and their hysteresis are ``small_frame``'s ``leave`` and
    ``large_frame``'s ``enter``."""
    return damp if mode != 0.0 else 0.0


def damped(damp, d, previous):
    """A deformation d seen with bond damping: d plus damp times its change since the previous
    step (damp = gamma_link / (2 dt), 0 with nothing to damp against)."""
    return fma(damp, d - previous, d)


def link_loads(W, s, rest, L, a1, a2, b1, b2, b3, ex, ey, ez, e1y, e1z, e2x, e2y, e2z):
    """The beam's force on the negative end and moments on both ends, in world axes (W: world
    from the beam's frame), for the damped deformation e; the beam constants a1 ... are the
    robot's reference ones, scaled by the link's stiffness s = E_link / E_ref. The axial term
    is E A_current strain: area and rest length both scale with the voxel size."""
    fax, fay, faz, max_, may, maz, mbx, mby, mbz = beam(
        ex * rest * (1.0 / L), ey, ez, 0.0, e1y, e1z, e2x, e2y, e2z, a1 * s, a2 * s,
        b1 * s, b2 * s, b3 * s)
    w00, w01, w02, w10, w11, w12, w20, w21, w22 = W
    return (dot3(w00, w01, w02, fax, fay, faz), dot3(w10, w11, w12, fax, fay, faz),
            dot3(w20, w21, w22, fax, fay, faz),
            dot3(w00, w01, w02, max_, may, maz), dot3(w10, w11, w12, max_, may, maz),
            dot3(w20, w21, w22, max_, may, maz),
            dot3(w00, w01, w02, mbx, mby, mbz), dot3(w10, w11, w12, mbx, mby, mbz),
            dot3(w20, w21, w22, mbx, mby, mbz))


def link_diverged(d, rest):
    """1 if the elongation d is beyond MAX_STRAIN times the rest length (or NaN), else 0."""
    return 0 if abs(d) <= MAX_STRAIN * rest else 1


def rest_length(size_a, size_b):
    """A link's rest length: the mean of its two voxels' current sizes."""
    return 0.5 * (size_a + size_b)


def link_frame(small, R, axis, rx, ry, rz, ow, ox, oy, oz, rest):
    """A link in the co-rotational frame ``small`` names (True: ``small_frame``, False:
    ``large_frame``), from its geometry (``link_geometry``) and rest length. Returns W (world
    from the beam's frame), its deformation d = (dx, dy, dz, t1y, t1z, t2x, t2y, t2z), and
    whether it changes frame (``small_frame``'s leave, ``large_frame``'s enter)."""
    if small:
        W, dx, dy, dz, t1y, t1z, t2x, t2y, t2z, change = small_frame(
            R, axis, rx, ry, rz, ow, ox, oy, oz, rest)
    else:
        W, dx, dy, dz, t1y, t1z, t2x, t2y, t2z, change = large_frame(
            R, axis, rx, ry, rz, ow, ox, oy, oz, rest)
    return W, (dx, dy, dz, t1y, t1z, t2x, t2y, t2z), change


def frame_mode(small):
    """The frame mode a link keeps for its next step: +1 small-angle, -1 large."""
    return 1.0 if small else -1.0


def reframe(small, R, axis, rx, ry, rz, ow, ox, oy, oz, rest):
    """The hysteresis transition of a link that has outgrown the frame ``small``
    (``link_frame``'s change): the link computed again in the other frame, undamped (its
    previous deformation was measured in this one), then flipped. Returns W, d (as
    ``link_frame``), the bond damping to apply (none) and its new frame mode."""
    W, d, _ = link_frame(not small, R, axis, rx, ry, rz, ow, ox, oy, oz, rest)
    return W, d, 0.0, frame_mode(not small)


def link_response(damp, W, d, previous, rest, constants):
    """A link's loads in world axes (``link_loads``) for its deformation d (``link_frame``)
    damped against ``previous``, the same eight values of its previous step (``damped``;
    the caller keeps d as the next step's previous), and whether it diverged
    (``link_diverged``). ``constants``: (stiffness scale E_link / E_ref, L, a1, a2, b1, b2,
    b3), the robot's in the link's precision."""
    dx, dy, dz, t1y, t1z, t2x, t2y, t2z = d
    p0, p1, p2, p3, p4, p5, p6, p7 = previous
    ex = damped(damp, dx, p0)
    ey = damped(damp, dy, p1)
    ez = damped(damp, dz, p2)
    e1y = damped(damp, t1y, p3)
    e1z = damped(damp, t1z, p4)
    e2x = damped(damp, t2x, p5)
    e2y = damped(damp, t2y, p6)
    e2z = damped(damp, t2z, p7)
    s, L, a1, a2, b1, b2, b3 = constants
    loads = link_loads(W, s, rest, L, a1, a2, b1, b2, b3, ex, ey, ez, e1y, e1z, e2x, e2y, e2z)
    return loads, link_diverged(dx, rest)


# ---------------------------------------------------------------- one self-contact pair
def contact_overlap(dx, dy, dz, size_i, size_j, reach):
    """How far voxels i and j (d = x_j - x_i) overlap, and their distance: contact begins
    at ``reach`` times the sum of their sizes. They touch when the overlap is positive and
    the distance is not zero. Candidates that do not touch (most of them, most steps) take
    no square root: their overlap is returned as -1, their distance as 0."""
    d2 = dx * dx + dy * dy + dz * dz
    touch = reach * (size_i + size_j)
    if not d2 < touch * touch:
        return -1.0, 0.0
    dist = math.sqrt(d2)
    return touch - dist, dist


def candidate_radius(L, reach, amp):
    """How near two surface voxels must be to be contact candidates: the largest distance at
    which they can touch (``reach`` times twice the largest actuated size) plus the margin."""
    return 2.0 * reach * L * (1.0 + amp) + COLLIDE_MARGIN * L


def contacts_stale(travel, L):
    """Whether the contact candidates may miss a touching pair: ``travel`` (a bound on half
    the spread of the surface voxels' displacements since they were listed, or that half
    spread measured: ``displacement_spread``) has reached half the margin. NaN counts as
    stale. Both tests of the rebuild trigger: a bound that reaches it has the spread
    measured, and a measured spread that reaches it has the list rebuilt."""
    return not (2.0 * travel < COLLIDE_MARGIN * L)


def travel_after(travel, speed2, dt):
    """The bound on half the surface's displacement spread after a step of dt whose fastest
    voxel had squared speed speed2 (-1: the step failed, nothing added)."""
    return travel + math.sqrt(max(speed2, 0.0)) * dt


def nan_min(a, b):
    """The smaller of a and b; b when either is NaN (a NaN b is kept)."""
    return b if not (b >= a) else a


def nan_max(a, b):
    """The larger of a and b; b when either is NaN (a NaN b is kept)."""
    return b if not (b <= a) else a


def widen(lo, hi, d):
    """The range [lo, hi] widened to hold d. A NaN d makes both ends NaN, and the next d
    replaces them: over values that are all NaN (positions before the first build) the range
    is NaN."""
    return nan_min(lo, d), nan_max(hi, d)


def displacement_spread(lo_x, hi_x, lo_y, hi_y, lo_z, hi_z):
    """Half the diagonal of the box (lo, hi) that holds every surface voxel's displacement since
    the contact candidates were listed: no two voxels' distance has changed by more than
    twice this, whatever motion they share (|d_ij' - d_ij| = |u_j - u_i|, both u in the box),
    so the list holds every touching pair while it stays below half the margin (the policy).
    NaN in, NaN out."""
    sx, sy, sz = hi_x - lo_x, hi_y - lo_y, hi_z - lo_z
    return 0.5 * math.sqrt(sx * sx + sy * sy + sz * sz)


def contact_push(overlap, dist, dx, dy, dz, vx, vy, vz, ki, kj, ci, cj, stiff, damp):
    """Penalty contact of touching voxels i and j (``contact_overlap``; d = x_j - x_i,
    v = v_j - v_i): the force on j (i gets its opposite). Stiffness ``stiff`` times the
    harmonic mean of the voxels' floor stiffnesses 2 E L (exactly it for one material),
    damping ``damp`` times the mean of their collision damping coefficients; the push never
    pulls. Swapping i and j gives the opposite force to the last bit."""
    k = stiff * (ki if ki == kj else 2.0 * ki * kj / (ki + kj))
    c = damp * (0.5 * (ci + cj))
    nx, ny, nz = dx / dist, dy / dist, dz / dist
    vn = vx * nx + vy * ny + vz * nz
    f = max(k * overlap - c * vn, 0.0)
    return f * nx, f * ny, f * nz


# ---------------------------------------------------------------- drag
def facet_drag(drag, pn, inv_m, nx, ny, nz):
    """The paper's engine's drag on one surface-mesh facet with N = (nx, ny, nz) = 2 A n
    (A its area, n its unit normal), moved by its voxel of momentum p (pn = p . N, inv_m
    that voxel's 1 / m): -drag A (v.n)^2 n = -drag/2 (p.N)^2 / (m^2 |N|^2) N when it moves
    into the fluid (pn > 0), else zero (``drag`` = 0.5 rho C_d). Without a branch (selects),
    so that the CPU's loop over the facets runs as vectors."""
    into = pn > 0.0
    norm2 = nx * nx + ny * ny + nz * nz
    f = -0.5 * drag * (pn * inv_m) * (pn * inv_m) / (norm2 if into else 1.0)
    return f * nx if into else 0.0, f * ny if into else 0.0, f * nz if into else 0.0


def facet_normal(ax, ay, az, bx, by, bz, cx, cy, cz):
    """N = (b - a) x (c - a) = 2 A n of the triangle (a, b, c): A its area, n its unit normal
    (outward for the surface mesh's winding)."""
    ux, uy, uz = bx - ax, by - ay, bz - az
    wx, wy, wz = cx - ax, cy - ay, cz - az
    return uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx


def facet_force(drag, ax, ay, az, bx, by, bz, cx, cy, cz, px, py, pz, inv_m):
    """The drag on the surface-mesh triangle (a, b, c) (``facet_drag`` of its
    ``facet_normal``), moved by its voxel of momentum p and 1 / m ``inv_m``."""
    nx, ny, nz = facet_normal(ax, ay, az, bx, by, bz, cx, cy, cz)
    return facet_drag(drag, px * nx + py * ny + pz * nz, inv_m, nx, ny, nz)


def corner_extents(size, L, exposed):
    """Where a voxel's mesh corners sit along its own axes, as signed offsets from its centre
    on each side (-x, +x, -y, +y, -z, +z): half its current size where it has a neighbour on
    that side, half the nominal size L where that face is exposed (``exposed``: its bits, as
    ``system.exposed_faces``; the fork places corners by the bonds' strains, and an exposed
    face has none)."""
    return (-(0.5 * (L if exposed & 1 else size)), 0.5 * (L if exposed & 2 else size),
            -(0.5 * (L if exposed & 4 else size)), 0.5 * (L if exposed & 8 else size),
            -(0.5 * (L if exposed & 16 else size)), 0.5 * (L if exposed & 32 else size))


def mesh_corner(c, xm, xp, ym, yp, zm, zp):
    """Offset of corner c (bits: x, y, z; 1 the + side) of a voxel from its centre in its own
    frame, from its ``corner_extents``."""
    return (xp if (c >> 2) & 1 else xm, yp if (c >> 1) & 1 else ym, zp if c & 1 else zm)


def corner_point(x, y, z, r00, r01, r02, r10, r11, r12, r20, r21, r22, ox, oy, oz):
    """A voxel's corner in world axes: its centre (x, y, z) plus its rotation (rows r) times
    the corner's offset o (``mesh_corner``). A surface-mesh vertex is the mean of this over
    the voxels that share it (the fork's vertex average), summed in their order in
    ``system.surface_mesh``'s ``mesh_vert``."""
    return (x + dot3(r00, r01, r02, ox, oy, oz), y + dot3(r10, r11, r12, ox, oy, oz),
            z + dot3(r20, r21, r22, ox, oy, oz))


def voxel_corner(c, x, y, z, R, size, L, exposed):
    """Corner c of a voxel (``mesh_corner``) in world axes (``corner_point``): its centre
    (x, y, z), rotation R (rows), current size and exposed faces (``corner_extents``)."""
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = R
    xm, xp, ym, yp, zm, zp = corner_extents(size, L, exposed)
    ox, oy, oz = mesh_corner(c, xm, xp, ym, yp, zm, zp)
    return corner_point(x, y, z, r00, r01, r02, r10, r11, r12, r20, r21, r22, ox, oy, oz)


def load_sum(a0, a1, a2, b0, b1, b2, sign):
    """A voxel's total of one row of its links' loads: the links it is the negative end of
    (a: on its +x, +y, +z faces) plus ``sign`` times those it is the positive end of (b: on
    its -x, -y, -z faces); a face without a link contributes 0. Forces take sign -1 (a link
    pushes its two ends oppositely), moments +1 (each end has its own row)."""
    return (a0 + a1 + a2) + sign * (b0 + b1 + b2)


def voxel_loads(a0, a1, a2, b0, b1, b2):
    """A voxel's force and moment from its links' loads (``link_loads``' nine values, float64):
    a0, a1, a2 of the links on its +x, +y, +z faces (it is their negative end: force rows
    0-2, moment rows 3-5), b0, b1, b2 of those on its -x, -y, -z faces (their positive end:
    minus the force, moment rows 6-8); zeros for a face without a link (``load_sum``)."""
    return (load_sum(a0[0], a1[0], a2[0], b0[0], b1[0], b2[0], -1.0),
            load_sum(a0[1], a1[1], a2[1], b0[1], b1[1], b2[1], -1.0),
            load_sum(a0[2], a1[2], a2[2], b0[2], b1[2], b2[2], -1.0),
            load_sum(a0[3], a1[3], a2[3], b0[6], b1[6], b2[6], 1.0),
            load_sum(a0[4], a1[4], a2[4], b0[7], b1[7], b2[7], 1.0),
            load_sum(a0[5], a1[5], a2[5], b0[8], b1[8], b2[8], 1.0))


# ---------------------------------------------------------------- the run around the steps
def frame_due(k, p):
    """Whether step k of the robot ``p`` records a frame (frame k // p.record)."""
    return p.record > 0 and k % p.record == 0


def com_due(k, p, taken, rows):
    """Whether step k takes a centre-of-mass sample: every ``p.com_every`` steps after
    settling, while fewer than rows - 1 were taken (the last row is the final position's)."""
    after = k - p.settle_steps
    return after >= 0 and after % p.com_every == 0 and taken < rows - 1


def step_status(diverged, insane, overfull):
    """How a step ended (``sim.system``'s STATUS_*), its failures in this order: a link
    diverged, a voxel left the sane range (or went NaN), a voxel has more contact candidates
    than the policy keeps; STATUS_OK if none."""
    if diverged:
        return STATUS_STRAIN
    if insane:
        return STATUS_NONFINITE
    if overfull:
        return STATUS_CONTACTS
    return STATUS_OK


def centre_of_mass(n, weights, stride, column, pos, vs, cs):
    """The centre of mass of n voxels: ``weights[v * stride + column]`` their mass weights
    (``V_WEIGHT``: m_i / max m, so exactly the mean position for one density), ``pos`` their
    positions, flat (voxel v's component c at ``vs * v + cs * c``: 3, 1 for (x, y, z) per
    voxel, 1, n for rows by component). Summed in voxel order, one axis after the other."""
    total = 0.0
    for v in range(n):
        total += weights[v * stride + column]
    cx, cy, cz = 0.0, 0.0, 0.0
    for v in range(n):
        cx += weights[v * stride + column] * pos[vs * v]
    for v in range(n):
        cy += weights[v * stride + column] * pos[vs * v + cs]
    for v in range(n):
        cz += weights[v * stride + column] * pos[vs * v + 2 * cs]
    return cx / total, cy / total, cz / total


def face_drag(fx, fy, fz, drag, exposed, qw, qx, qy, qz, vx, vy, vz, area):
    """The force (fx, fy, fz) plus the quadratic drag -0.5 rho C_d s^2 v_n^2 n (``drag`` =
    0.5 rho C_d) of each exposed face moving outward (v_n > 0); ``exposed`` has bit f set when
    face f (ordered -x, +x, -y, +y, -z, +z) has no neighbour. Without a branch: a face that
    does not drag adds nothing (a select, so vector loops take it)."""
    for a in range(3):
        ex, ey, ez = qrot(qw, qx, qy, qz, 1.0 if a == 0 else 0.0, 1.0 if a == 1 else 0.0,
                          1.0 if a == 2 else 0.0)
        for side in range(2):
            sgn = 1.0 if side == 1 else -1.0
            vn = sgn * (vx * ex + vy * ey + vz * ez)
            f = -drag * area * vn * vn * sgn
            on = ((exposed >> (2 * a + side)) & 1 != 0) & (vn > 0.0)
            fx = fx + f * ex if on else fx
            fy = fy + f * ey if on else fy
            fz = fz + f * ez if on else fz
    return fx, fy, fz


# ---------------------------------------------------------------- one voxel
def voxel_update(world, own, exposed, size, fixed, fx, fy, fz, mx, my, mz, x, y, z, qw, qx, qy,
                 qz, px, py, pz, lx, ly, lz, static):
    """Everything that acts on one voxel alone, then its step.

    In: the step's constants ``world`` = (dt, gravity g, water drag, in water, on land,
    friction mu_s and mu_k, ``fork``: the paper's engine's friction rule, ``slide``: the
    speed below which a voxel counts as still), the voxel's constants ``own`` = (mass m,
    1 / m, 1 / I, global damping c_lin and c_ang, floor stiffness, collision damping), its
    exposed faces (bits), current size and whether it is fixed; the force f (links,
    collisions and external, summed) and moment m of the links; its state (position x,
    orientation q, momenta p and l) and whether static friction holds it.

    - world forces: gravity -m g z, global damping -c_lin v and -c_ang omega, in water the
      drag on its exposed faces (``face_drag``);
    - on land a penalty floor at z = 0 with static and kinetic (Coulomb) friction: a static
      voxel starts to slide when the horizontal force exceeds mu_s times the normal force; a
      sliding one feels mu_k times the normal force against its horizontal velocity (with
      ``fork``: a voxel at rest is held while the horizontal force is below mu_s N; a moving
      one stops dead when mu_k N dt would take all its momentum);
    - semi-implicit Euler: momenta first, then position and orientation from the new
      momenta; a sliding voxel in floor contact sticks when friction would reverse it
      (work-energy), and a static one keeps no horizontal momentum. A fixed voxel keeps its
      place and orientation and has zero momenta.

    Returns the new state (x, q, p, l), static, whether it touches the floor, its squared
    speed, whether it stayed in the sane range, and ``turn``: whether its rotation this step
    is past ``quat_from_small_rotvec``'s series. A voxel that turns keeps its orientation q
    here; ``voxel_turn`` gives the new one (rare: a second pass over the voxels on the CPU).

    Without a branch on a voxel's values (each choice a select between values computed
    either way), so that the CPU's loop over the voxels runs as vectors; ``world``'s
    switches are the same for every voxel. (Calls take at most 30 arguments: CPython passes
    more as a tuple, which numba cannot inline.)"""
    dt, g, drag, water, land, mu_s, mu_k, fork, slide = world
    m, inv_m, inv_i, c_lin, c_ang, kfloor, ccoll = own
    held_before = static
    vx, vy, vz = px * inv_m, py * inv_m, pz * inv_m
    fx = fma(-c_lin, vx, fx)
    fy = fma(-c_lin, vy, fy)
    fz = fma(-c_lin, vz, fz) - m * g
    w_ang = c_ang * inv_i
    mx = fma(-w_ang, lx, mx)
    my = fma(-w_ang, ly, my)
    mz = fma(-w_ang, lz, mz)
    if water:
        fx, fy, fz = face_drag(fx, fy, fz, drag, exposed, qw, qx, qy, qz, vx, vy, vz,
                               size * size)

    # floor contact and friction
    touch = False
    if land:
        pen = 0.5 * size - z
        touch = pen >= 0.0
        normal = kfloor * pen
        fz = fz + (normal - ccoll * vz) if touch else fz
        hv = math.sqrt(vx * vx + vy * vy)
        across = hv if hv > 0.0 else 1.0  # kinetic friction is only taken when hv > 0
        kx = fx - mu_k * normal * vx / across  # with kinetic friction
        ky = fy - mu_k * normal * vy / across
        if fork:  # the paper's engine (CalcFloorEffect)
            still = (vx == 0.0) & (vy == 0.0)  # at rest: held while the force is below mu_s N
            held = fx * fx + fy * fy < (mu_s * normal) ** 2
            stops = mu_k * normal * dt >= m * hv  # moving: friction would stop it
            slides = touch & (not still) & (not stops)
            static = touch & ((still & held) | ((not still) & stops))
        else:
            slides = touch & (not static) & (hv > slide)
            static = touch & static & (not (fx * fx + fy * fy > (mu_s * normal) ** 2))
        fx = kx if slides else fx
        fy = ky if slides else fy

    # semi-implicit Euler
    px, py, pz = fma(fx, dt, px), fma(fy, dt, py), fma(fz, dt, pz)
    work_ = (fx * px + fy * py) * inv_m * dt
    sticks = touch & (not fork) & (0.5 * inv_m * (px * px + py * py) + work_ <= 0.0)
    static = static | sticks
    px = 0.0 if (touch & static) | fixed else px
    py = 0.0 if (touch & static) | fixed else py
    pz = 0.0 if fixed else pz
    step_m = inv_m * dt
    x = fma(px, step_m, x)
    y = fma(py, step_m, y)
    z = fma(pz, step_m, z)
    speed2 = dot3(px, py, pz, px, py, pz) * (inv_m * inv_m)

    lx, ly, lz = fma(mx, dt, lx), fma(my, dt, ly), fma(mz, dt, lz)
    lx = 0.0 if fixed else lx
    ly = 0.0 if fixed else ly
    lz = 0.0 if fixed else lz
    step_i = inv_i * dt
    dw, dx, dy, dz, turn = quat_from_small_rotvec(lx * step_i, ly * step_i, lz * step_i)
    nw, nx, ny, nz = turned(dw, dx, dy, dz, qw, qx, qy, qz)
    keep = turn | fixed
    qw, qx = qw if keep else nw, qx if keep else nx
    qy, qz = qy if keep else ny, qz if keep else nz
    static = held_before if fixed else static
    touch = touch & (not fixed)
    ok = ((abs(x) < POSITION_BOUND) & (abs(y) < POSITION_BOUND) & (abs(z) < POSITION_BOUND)
          & (abs(qw) <= 1.0 + 1e-9))
    return x, y, z, qw, qx, qy, qz, px, py, pz, lx, ly, lz, static, touch, speed2, ok, turn


def turned(dw, dx, dy, dz, qw, qx, qy, qz):
    """The orientation q turned by the unit quaternion d, renormalised."""
    qw, qx, qy, qz = qmul(dw, dx, dy, dz, qw, qx, qy, qz)
    norm = 1.0 / math.sqrt(fma(qw, qw, dot3(qx, qy, qz, qx, qy, qz)))
    return qw * norm, qx * norm, qy * norm, qz * norm


def voxel_turn(inv_i, dt, lx, ly, lz, qw, qx, qy, qz):
    """The new orientation of a voxel whose ``voxel_update`` said ``turn`` (its new angular
    momentum l and its orientation q as that left them), exact, and whether it stayed in the
    sane range."""
    step_i = inv_i * dt
    dw, dx, dy, dz = quat_from_large_rotvec(lx * step_i, ly * step_i, lz * step_i)
    qw, qx, qy, qz = turned(dw, dx, dy, dz, qw, qx, qy, qz)
    return qw, qx, qy, qz, abs(qw) <= 1.0 + 1e-9


def voxel_world(p):
    """The step's constants ``voxel_update`` takes as ``world``, from a robot's ``Params``:
    (dt, gravity, water drag, in water with drag, on land, mu_s, mu_k, the fork's friction
    rule, the speed below which a voxel counts as still)."""
    return (p.dt, p.gravity, p.drag, p.env == ENV_WATER and p.drag > 0.0, p.env == ENV_LAND,
            p.mu_s, p.mu_k, p.friction == FRICTION_VOXCAD, FRICTION_EPS * p.L / p.dt)


# ---------------------------------------------------------------- targets
PIECES = (
    "dot3", "qmul", "qrot", "angle_over_sin", "rotvec", "qmul_x0", "rotvec_x0",
    "quat_from_rotvec", "quat_from_small_rotvec", "quat_from_large_rotvec", "rotation_matrix",
    "waveform", "actuated_size", "actuation", "voxel_size",
    "to_link", "from_link_matrix", "beam", "link_geometry", "small_frame", "large_frame",
    "frame_damping", "damped", "link_loads", "link_diverged", "rest_length", "link_frame",
    "frame_mode", "reframe", "link_response", "candidate_radius", "contact_overlap",
    "contacts_stale", "travel_after", "nan_min", "nan_max", "widen", "displacement_spread",
    "contact_push", "facet_drag", "facet_normal", "facet_force", "corner_extents", "mesh_corner",
    "corner_point", "voxel_corner", "load_sum", "voxel_loads", "frame_due", "com_due", "step_status",
    "centre_of_mass", "face_drag", "voxel_update", "turned", "voxel_turn", "voxel_world",
)


def compiled(jit, fma_impl, real=None) -> SimpleNamespace:
    """The functions of ``PIECES`` compiled by ``jit`` (a decorator; the identity gives the
    plain functions), each calling the others' compiled versions and ``fma_impl`` for
    ``fma``. Compilation itself is lazy, at a piece's first use in a compiled caller.

    ``real``: None (float64, the functions as written) or a scalar type such as
    ``numpy.float32``, which every float constant of the copies (their literals and the
    module's float constants, ``ANGLE_OVER_SIN`` included) becomes, so that a copy given
    float32 arguments computes in float32 (a float64 literal would promote every expression
    it enters to float64). Integer literals stay integers: the pieces never multiply a float
    by one."""
    space = dict(globals())
    space["fma"] = fma_impl
    if real is not None:
        space.update({key: _as_real(value, real) for key, value in globals().items()
                      if _is_float_constant(value)})
    return bind(jit, [globals()[name] for name in PIECES], space, real)


def bind(jit, functions, space, real=None) -> SimpleNamespace:
    """Copies of ``functions`` whose global names resolve in ``space`` (a dict, which each
    copy joins under its name, compiled by ``jit``, so that the copies call one another), their
    float literals as ``real`` when it is given (``compiled``). Returns them by name. The way
    ``sim.substeps`` compiles its pieces against a target's physics."""
    for f in functions:
        code = f.__code__
        if real is not None:
            code = code.replace(co_consts=tuple(_as_real(c, real) if _is_float_constant(c) else c
                                                for c in code.co_consts))
        copy = types.FunctionType(code, space, f.__name__, f.__defaults__, f.__closure__)
        copy.__doc__, copy.__qualname__, copy.__module__ = f.__doc__, f.__qualname__, f.__module__
        space[f.__name__] = jit(copy)
    return SimpleNamespace(**{f.__name__: space[f.__name__] for f in functions})


def _is_float_constant(value) -> bool:
    """A float, or a non-empty tuple of floats (``ANGLE_OVER_SIN``)."""
    if type(value) is float:
        return True
    return type(value) is tuple and bool(value) and all(type(v) is float for v in value)


def _as_real(value, real):
    """``value`` (``_is_float_constant``) as ``real``."""
    if type(value) is tuple:
        return tuple(real(v) for v in value)
    return real(value)
