"""The engine against closed-form mechanics and conservation laws.

Each test derives its expectation from textbook mechanics (Euler-Bernoulli beams with lumped
nodal loads, Newton's laws, the drag ODE, Coulomb friction), never from the engine's own
earlier output, so a wrong force, sign, unit or integrator fails here. Tolerances are argued
from the physics next to each assertion.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.sim._support import (
    com_trajectory,
    frames,
    line,
    period_of,
    report,
    simulate,
    voxel_index,
)
from tests.sim.scenes import actuated_scene

# Every test runs in each precision (``sim.models.PRECISIONS``): float64, and "mixed" (the
# links in float32). The tolerances below hold for both: each is argued from the physics and
# is at least 1e-3 relative, far above float32's 6e-8 rounding of a link's deformation.
pytestmark = pytest.mark.usefixtures("precision")

G = 9.81
AXES = "xyz"

# A stiff slender bar: deflections stay ~1% of the span, so geometric nonlinearity (relative
# error ~ (deflection / span)^2 ~ 1e-4) is far below the tolerances used below.
BEAM = {"voxel_size": 0.01, "density": 1000.0, "youngs_modulus": 1e7, "n": 10}


def _beam_scene(axis: int, gravity: float, forces: list, seconds: float = 0.5) -> dict:
    L, E, rho = BEAM["voxel_size"], BEAM["youngs_modulus"], BEAM["density"]
    return {
        "voxel_size": L,
        "material": {"youngs_modulus": E, "density": rho},
        "environment": {"kind": "void", "gravity": gravity},
        "body": line(BEAM["n"], axis),
        "fixed": [[0, 0, 0]],
        "forces": forces,
        "duration": {"seconds": seconds},
        "self_collisions": False,
        "record": {"every": 100},
    }


def _settled_displacement(result, tail_from: float) -> np.ndarray:
    """Mean displacement (n_voxels, 3) of every voxel over frames with t >= tail_from."""
    t, pos = frames(result)
    assert t[-1] > tail_from
    return pos[t >= tail_from].mean(axis=0) - pos[0]


def _eb_cantilever(x: np.ndarray, a: float, load: float, ei: float) -> np.ndarray:
    """Deflection at x of a cantilever clamped at 0 under a point load at a (Euler-Bernoulli)."""
    x = np.asarray(x, dtype=float)
    near = load * x**2 * (3 * a - x) / (6 * ei)
    far = load * a**2 * (3 * x - a) / (6 * ei)
    return np.where(x <= a, near, far)


def _beam_constants():
    L, E, rho, n = BEAM["voxel_size"], BEAM["youngs_modulus"], BEAM["density"], BEAM["n"]
    ei = E * L**4 / 12.0
    x = np.arange(n) * L  # distance of each voxel centre from the fixed voxel's centre
    return L, E, rho, n, ei, x


@pytest.mark.parametrize("axis", [0, 1])
def test_cantilever_under_gravity_matches_lumped_euler_bernoulli(axis):
    """Loads m g at every free voxel centre; deflection = superposition of point loads.

    Frame elements are exact for nodal loads, so the only model error is geometric
    nonlinearity (~1e-4 here); 1.5% of the tip deflection leaves room for the residual of
    the settling oscillation averaged over the last 0.2 s.
    """
    L, E, rho, n, ei, x = _beam_constants()
    m = rho * L**3
    result = simulate(_beam_scene(axis, G, [], seconds=0.5))
    index = voxel_index(result)
    disp = _settled_displacement(result, 0.3)
    order = [index[tuple(i if d == axis else 0 for d in range(3))] for i in range(n)]
    got = -disp[order, 2]
    expected = sum(_eb_cantilever(x, a, m * G, ei) for a in x[1:])
    tip_ratio = got[-1] / expected[-1]
    report(f"analytic.cantilever_gravity.{AXES[axis]}", tip_expected_m=expected[-1],
           tip_got_m=got[-1], ratio=tip_ratio)
    np.testing.assert_allclose(got, expected, rtol=0, atol=0.015 * expected[-1])


@pytest.mark.parametrize(("axis", "load_axis"), [(0, 2), (0, 1), (1, 0), (1, 2), (2, 0), (2, 1)])
def test_cantilever_tip_load_is_PL3_over_3EI(axis, load_axis):
    """Tip load P: tip deflection P l^3 / (3 E I), l = (n - 1) L; the whole curve too.

    Every bar orientation and both transverse directions, so a sign slip in one bending
    plane of the link frame cannot hide. Tolerance as for the gravity cantilever.
    """
    L, E, rho, n, ei, x = _beam_constants()
    span = x[-1]
    load = 0.03  # N: tip deflection ~1e-3 m, ~1% of the span
    tip = [n - 1 if d == axis else 0 for d in range(3)]
    force = [0.0, 0.0, 0.0]
    force[load_axis] = load
    result = simulate(_beam_scene(axis, 0.0, [{"voxel": tip, "force": force}]))
    index = voxel_index(result)
    disp = _settled_displacement(result, 0.3)
    order = [index[tuple(i if d == axis else 0 for d in range(3))] for i in range(n)]
    got = disp[order, load_axis]
    expected = _eb_cantilever(x, span, load, ei)
    assert expected[-1] == pytest.approx(load * span**3 / (3 * ei))
    report(f"analytic.cantilever_tip.{AXES[axis]}{AXES[load_axis]}",
           tip_expected_m=expected[-1], tip_got_m=got[-1], ratio=got[-1] / expected[-1])
    np.testing.assert_allclose(got, expected, rtol=0, atol=0.015 * expected[-1])
    other = [d for d in range(3) if d not in (axis, load_axis)][0]
    assert np.abs(disp[:, other]).max() < 1e-3 * expected[-1]  # no out-of-plane motion


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_axial_stretch_is_F_L_over_EA(axis):
    """Axial tip force F: voxel i moves F x_i / (E A), A = L^2 (links in series, a1 = E L).

    Strain 1e-3, so any strain-dependent area or nonlinear-material effect is ~1e-3 of the
    answer; 1% tolerance.
    """
    L, E, rho, n, ei, x = _beam_constants()
    force_n = E * L**2 * 1e-3
    tip = [n - 1 if d == axis else 0 for d in range(3)]
    force = [0.0, 0.0, 0.0]
    force[axis] = force_n
    result = simulate(_beam_scene(axis, 0.0, [{"voxel": tip, "force": force}], seconds=0.3))
    index = voxel_index(result)
    disp = _settled_displacement(result, 0.2)
    order = [index[tuple(i if d == axis else 0 for d in range(3))] for i in range(n)]
    got = disp[order, axis]
    expected = force_n * x / (E * L**2)
    report(f"analytic.axial.{AXES[axis]}", tip_expected_m=expected[-1], tip_got_m=got[-1],
           ratio=got[-1] / expected[-1])
    np.testing.assert_allclose(got, expected, rtol=0, atol=0.01 * expected[-1])


def test_free_fall_is_g_t2_over_2():
    """Void with gravity, no damping: z(t) = z0 - g t^2 / 2 for the centre of mass.

    Semi-implicit Euler lags the exact parabola by g t dt / 2; allow g t dt. The body must
    not deform (uniform gravity) nor move sideways.
    """
    L, rho, E = 0.05, 1200.0, 1e6
    scene = {
        "voxel_size": L,
        "material": {"youngs_modulus": E, "density": rho, "damping_global": 0.0},
        "environment": {"kind": "void", "gravity": G},
        "body": np.ones((2, 2, 2), int).tolist(),
        "duration": {"seconds": 0.5},
        "record": {"every": 50},
    }
    result = simulate(scene)
    t, com = com_trajectory(result)
    dt = result.dt
    expected = L - 0.5 * G * t**2  # the 2x2x2 block's centre starts at z = L
    err = np.abs(com[:, 2] - expected)
    report("analytic.free_fall", drop_expected_m=0.5 * G * t[-1] ** 2,
           drop_got_m=com[0, 2] - com[-1, 2], max_abs_err_m=err.max(), allowed_m=G * t[-1] * dt)
    assert np.all(err <= G * t * dt + 1e-9)
    assert np.abs(com[:, :2] - com[0, :2]).max() < 1e-9
    _, pos = frames(result)
    shape0 = pos[0] - pos[0].mean(axis=0)
    shape1 = pos[-1] - pos[-1].mean(axis=0)
    assert np.abs(shape1 - shape0).max() < 1e-9


@pytest.mark.parametrize("direction", [(1.0, 0.0, 0.0), (0.0, -1.0, 0.0), (1.0, 1.0, 0.0)])
def test_drag_decay_of_a_coasting_voxel(direction):
    """One voxel coasting in water, all damping off: each face moving into the fluid gets
    -1/2 rho Cd A (v.n)^2 n, so each velocity component obeys m dv/dt = -k v^2,
    k = 1/2 rho Cd L^2: v(t) = v0 / (1 + k v0 t / m), x(t) = (m / k) ln(1 + k v0 t / m).

    The diagonal case checks that drag is per face ((v.n)^2 per face), not |v|^2 along v.
    Time discretisation error is O(dt / t) ~ 1e-4; 0.5% tolerance on position, 1% on the
    finite-difference velocity (sampling error ~ (k v dt_s / m)^2).
    """
    L, rho, E = 0.05, 1200.0, 1e6
    rho_f, cd, v0 = 1000.0, 1.5, 0.1
    d = np.asarray(direction) / np.linalg.norm(direction)
    v_init = v0 * d
    scene = {
        "voxel_size": L,
        "material": {"youngs_modulus": E, "density": rho, "damping_global": 0.0,
                     "damping_bond": 0.0},
        "environment": {"kind": "water", "fluid_density": rho_f, "drag_coefficient": cd},
        "body": [[[1]]],
        "initial_velocity": v_init.tolist(),
        "duration": {"seconds": 2.0},
        "record": {"every": 100},
    }
    result = simulate(scene)
    t, com = com_trajectory(result)
    m = rho * L**3
    k = 0.5 * rho_f * cd * L**2
    for axis in range(3):
        u0 = v_init[axis]
        if u0 == 0.0:
            assert np.abs(com[:, axis] - 0.5 * L).max() < 1e-9
            continue
        sign = math.copysign(1.0, u0)
        expected_x = sign * (m / k) * np.log1p(k * abs(u0) * t / m)
        got_x = com[:, axis] - 0.5 * L  # the voxel starts centred at L / 2
        mid = 0.5 * (t[1:] + t[:-1])
        got_v = np.diff(got_x) / np.diff(t)
        expected_v = u0 / (1 + k * abs(u0) * mid / m)
        report(f"analytic.drag.{AXES[axis]}_{'_'.join(f'{c:g}' for c in direction)}",
               x_expected_m=expected_x[-1], x_got_m=got_x[-1], ratio=got_x[-1] / expected_x[-1],
               v_end_expected=expected_v[-1], v_end_got=got_v[-1])
        np.testing.assert_allclose(got_x, expected_x, rtol=0, atol=0.005 * abs(expected_x[-1]))
        np.testing.assert_allclose(got_v, expected_v, rtol=0.01, atol=1e-6)
    disp = np.asarray(result.displacement)
    assert result.distance == pytest.approx(np.linalg.norm(disp) / L, rel=1e-9)  # 3-D in water


def _oscillator(fixed: bool, seconds: float):
    L, rho, E = 0.05, 1200.0, 1e6
    force = 5.0
    scene = {
        "voxel_size": L,
        "material": {"youngs_modulus": E, "density": rho, "damping_bond": 0.0,
                     "damping_global": 0.0, "damping_collision": 0.0},
        "environment": {"kind": "void"},
        "body": line(2),
        "fixed": [[0, 0, 0]] if fixed else [],
        "forces": [{"voxel": [1, 0, 0], "force": [force, 0.0, 0.0]}],
        "duration": {"seconds": seconds},
        "self_collisions": False,
        "record": {"every": 1},
    }
    result = simulate(scene)
    t, pos = frames(result)
    index = voxel_index(result)
    a, b = pos[:, index[(0, 0, 0)]], pos[:, index[(1, 0, 0)]]
    stretch = (b[:, 0] - a[:, 0]) - L
    return t, a, b, stretch, force, E * L, rho * L**3, result


def _check_undamped(t, stretch, static, period_expected, name):
    """Period, amplitude and its constancy (energy conservation) of u = static (1 - cos wt).

    Symplectic Euler at w dt ~ 0.11-0.16 rad: period error ~ (w dt)^2 / 24 ~ 0.1%, peak error
    ~ (w dt)^2 / 8 ~ 0.3% (plus sampling at every step): 0.5% on the period, 1% on the
    amplitude. With damping off the amplitude must not decay: first and last five periods
    agree within 0.5% (any physical damping of even zeta = 0.001 loses ~15% over 50 periods).
    """
    period = period_of(t, stretch, crossings=10)
    first = t < t[0] + 5 * period_expected
    last = t > t[-1] - 5 * period_expected
    amp_first = np.ptp(stretch[first])
    amp_last = np.ptp(stretch[last])
    report(name, period_expected_s=period_expected, period_got_s=period,
           period_ratio=period / period_expected, amplitude_expected_m=2 * static,
           amplitude_first_m=amp_first, amplitude_last_m=amp_last,
           amplitude_kept=amp_last / amp_first)
    assert period == pytest.approx(period_expected, rel=0.005)
    assert amp_first == pytest.approx(2 * static, rel=0.01)
    assert amp_last == pytest.approx(amp_first, rel=0.005)


def test_energy_conserved_fixed_oscillator():
    """Voxel 0 fixed, constant force F on voxel 1, no damping: m u'' = -k u + F with
    k = a1 = E L, so u = (F / k)(1 - cos wt), w = sqrt(k / m): energy (kinetic + elastic +
    load potential) conserved means the amplitude 2 F / k never decays."""
    t0 = 2 * math.pi * math.sqrt(1200.0 * 0.05**3 / (1e6 * 0.05))
    t, a, b, stretch, force, k, m, _ = _oscillator(True, 50 * t0)
    assert np.abs(a - a[0]).max() == 0.0  # the fixed voxel does not move at all
    period = 2 * math.pi * math.sqrt(m / k)
    _check_undamped(t, stretch, force / k, period, "analytic.oscillator_fixed")


def test_energy_conserved_free_pair_and_newton_second_law():
    """Two free voxels, force F on one, no damping: the stretch oscillates with the reduced
    mass, u = (F / 2k)(1 - cos wt), w = sqrt(k / m_red), m_red = m / 2; the centre of mass
    accelerates at F / 2m exactly (semi-implicit Euler error g t dt / 2, allowed a t dt)."""
    m = 1200.0 * 0.05**3
    k = 1e6 * 0.05
    period = 2 * math.pi * math.sqrt((m / 2) / k)
    t, a, b, stretch, force, k, m, result = _oscillator(False, 50 * period)
    _check_undamped(t, stretch, force / (2 * k), period, "analytic.oscillator_free_pair")
    com_x = 0.5 * (a[:, 0] + b[:, 0])
    accel = force / (2 * m)
    expected = com_x[0] + 0.5 * accel * t**2
    assert np.all(np.abs(com_x - expected) <= accel * t * result.dt + 1e-12)


def _random_body(rng: np.random.Generator, side: int, fill: float) -> np.ndarray:
    body = (rng.random((side, side, side)) < fill).astype(int)
    body[body == 1] = rng.choice([1, 2], size=int(body.sum()), p=[0.3, 0.7])
    body[side // 2, side // 2, side // 2] = 2
    return body


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_centre_of_mass_fixed_in_void_under_actuation(seed):
    """Internal forces (links, bond damping, self-collision) are equal and opposite and the
    global damping of equal-mass voxels sums to -c P_total = 0, so the COM cannot move.

    Soft (1e5 Pa), strong actuation, random phases and self-collisions on: the body folds
    and touches itself. Round-off alone leaves ~1e-13 m; allow 1e-9 voxel lengths.
    """
    rng = np.random.default_rng(seed)
    body = _random_body(rng, 4, 0.6)
    scene = actuated_scene(body, rng, "void", cycles=3, every=20)
    L = scene["voxel_size"]
    result = simulate(scene)
    t, com = com_trajectory(result)
    _, pos = frames(result)
    moved = np.abs(pos[-1] - pos[0]).max() / L
    drift = np.abs(com - com[0]).max() / L
    report(f"conservation.com_void.seed{seed}", voxels=len(result.voxels),
           max_voxel_motion_L=moved, com_drift_L=drift)
    assert moved > 0.05  # the actuation really moved the body
    assert drift < 1e-9
    assert np.linalg.norm(result.displacement) / L < 1e-9


def _resting_scene(body: np.ndarray, settle: float, seconds: float) -> dict:
    return {
        "voxel_size": 0.05,
        "material": {"youngs_modulus": 1e6},
        "environment": {"kind": "land"},
        "body": body.tolist(),
        "settle_seconds": settle,
        "duration": {"seconds": seconds},
    }


@pytest.mark.parametrize("shape", ["block", "ell"])
def test_resting_block_does_not_creep(shape):
    """A passive body at rest on the floor stays put: after settling, the horizontal COM
    drift over 2 s must be below 1e-6 voxel lengths (static friction holds exactly).

    The 'ell' is asymmetric: gravity tilts it a little, which static friction must resist.
    """
    if shape == "block":
        body = np.ones((3, 3, 2), int)
    else:
        body = np.zeros((3, 2, 3), int)
        body[:, :, 0] = 1
        body[0, :, :] = 1
    result = simulate(_resting_scene(body, settle=1.0, seconds=2.0))
    report(f"land.resting_{shape}", drift_L=result.distance)
    assert result.distance < 1e-6


def test_resting_column_sag_matches_springs_in_series():
    """A 1x1x3 column on the floor settles where the floor (k_p = 2 E L per voxel) carries
    3 m g and the two links (k = E L) carry 2 m g and m g. The sags (~1e-4 L) come from
    linear springs; 2% covers the residual of the damped bounce after 1 s."""
    L, rho, E = 0.05, 1200.0, 1e5
    m = rho * L**3
    result = simulate({
        "voxel_size": L, "material": {"youngs_modulus": E, "density": rho},
        "environment": {"kind": "land"}, "body": line(3, axis=2),
        "duration": {"seconds": 1.0},
    })
    index = voxel_index(result)
    z = np.asarray(result.final_positions)[[index[(0, 0, k)] for k in range(3)], 2]
    rest = (np.arange(3) + 0.5) * L
    k_floor, k_link = 2 * E * L, E * L
    sag0 = 3 * m * G / k_floor
    expected = np.array([sag0, sag0 + 2 * m * G / k_link, sag0 + 3 * m * G / k_link])
    got = rest - z
    report("land.column_sag", expected_m=expected.tolist(), got_m=got.tolist(),
           ratio_top=got[2] / expected[2])
    np.testing.assert_allclose(got, expected, rtol=0.02)


def _friction_scene(body, force_total, mu_s, mu_k, seconds, settle=0.0, damping_global=0.0,
                    preloaded=False):
    """Horizontal force ``force_total`` (N, along +x) split evenly over the body's voxels.

    ``preloaded``: start each (single-layer) voxel sunk into the floor by its equilibrium
    penetration m g / k_p (k_p = 2 E L), so the normal force is m g from the first step.
    """
    body = np.asarray(body)
    L, rho, E = 0.05, 1200.0, 1e6
    sink = rho * L**3 * G / (2 * E * L) if preloaded else 0.0
    full = [list(map(int, v)) for v in np.argwhere(body > 0)]
    per = force_total / len(full)
    return {
        "voxel_size": 0.05,
        "material": {"youngs_modulus": 1e6, "density": 1200.0, "friction_static": mu_s,
                     "friction_kinetic": mu_k, "damping_global": damping_global},
        "environment": {"kind": "land", "gravity": G},
        "body": body.tolist(),
        "forces": [{"voxel": v, "force": [per, 0.0, 0.0]} for v in full],
        "settle_seconds": settle,
        "duration": {"seconds": seconds},
        "initial_offset": [0.0, 0.0, -sink],
        "record": {"every": 50},
    }


def _assert_slides(t, com, force: float, mu_k: float, m: float, name: str) -> None:
    """Once sliding (t >= 0.1 s) the centre of mass accelerates at (F - mu_k m g) / m, the
    kinetic friction law, within 2%."""
    late = t >= 0.1
    accel = 2 * np.polyfit(t[late], com[late, 0], 2)[0]
    expected = (force - mu_k * m * G) / m
    report(name, accel_expected=expected, accel_got=accel, ratio=accel / expected)
    assert accel == pytest.approx(expected, rel=0.02)


@pytest.mark.parametrize("factor", [0.95, 1.05])
@pytest.mark.parametrize("body", [[[[1]]], np.ones((2, 2, 1), int).tolist()])
def test_friction_threshold_from_equilibrium(body, factor):
    """The friction threshold itself, with mu_s = 1 and mu_k = 0.5 far apart.

    Starting at the equilibrium penetration (normal force m g from the first step), a
    horizontal force of 0.95 mu_s m g must not move the body at all (< 1e-6 voxel lengths in
    1 s), while 1.05 mu_s m g must slide it at (F - mu_k m g) / m (fitted over 0.1-1 s, 2%).
    A static threshold at mu_k, or no static friction, fails the first; a wrong kinetic law
    fails the second.
    """
    mu_s, mu_k = 1.0, 0.5
    n = int(np.sum(body))
    m = 1200.0 * 0.05**3 * n
    force = factor * mu_s * m * G
    result = simulate(_friction_scene(body, force, mu_s, mu_k, 1.0, preloaded=True))
    t, com = com_trajectory(result)
    if factor < 1:
        report(f"land.friction_threshold.n{n}.below", drift_L=result.distance)
        assert result.distance < 1e-6
        return
    _assert_slides(t, com, force, mu_k, m, f"land.friction_threshold.n{n}.above")


@pytest.mark.parametrize("body", [[[[1]]], np.ones((2, 2, 1), int).tolist()])
def test_friction_holds_after_touchdown(body):
    """F = 0.95 mu_s m g: static friction holds (after touchdown) and nothing creeps.

    The body starts touching the floor with zero normal force, so during the first
    millisecond of touchdown any horizontal force slides it a little; with mu_k = mu_s the
    slip is arrested at (mu_k m g - F) / m = 0.05 g within ~0.02 s, well inside the 0.5 s of
    settling. After that the body must not move: drift < 1e-6 voxel lengths in 1 s.
    """
    n = int(np.sum(body))
    m = 1200.0 * 0.05**3 * n
    result = simulate(_friction_scene(body, 0.95 * 1.0 * m * G, 1.0, 1.0, 1.0, settle=0.5,
                                      damping_global=0.01))
    report(f"land.friction_hold.n{n}", drift_L=result.distance)
    assert result.distance < 1e-6


@pytest.mark.parametrize("mu_k", [0.5, 0.25])
@pytest.mark.parametrize("body", [[[[1]]], np.ones((2, 2, 1), int).tolist()])
def test_friction_slides_above_static_threshold(body, mu_k):
    """F = 1.05 mu_s m g: the body slides with a = (F - mu_k m g) / m (no global damping).

    The acceleration is fitted to x(t) over 0.1-1 s, after touchdown; the normal force is
    then m g to within the floor bounce (collision damping 0.8 kills it in ~10 ms): 2%.
    """
    mu_s = 1.0
    n = int(np.sum(body))
    m = 1200.0 * 0.05**3 * n
    force = 1.05 * mu_s * m * G
    result = simulate(_friction_scene(body, force, mu_s, mu_k, 1.0))
    t, com = com_trajectory(result)
    _assert_slides(t, com, force, mu_k, m, f"land.friction_slide.n{n}.mu_k{mu_k}")
    assert np.abs(com[:, 1] - com[0, 1]).max() < 1e-9  # no sideways motion
