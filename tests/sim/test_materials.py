"""Per-voxel materials and frequencies against closed-form mechanics.

Scenes with ``youngs_modulus_field``, ``density_field`` and ``frequency_field`` (sim.scene).
Each expectation is derived here from textbook mechanics with the engine's stated model: a link
between voxels of moduli E_a, E_b is two half-beams in series, E_link = 2 E_a E_b / (E_a + E_b);
a voxel's mass is rho_i L^3; an active voxel's size is L (1 + a sin(2 pi f_i t + phase_i)).
Never the engine's own earlier output. Tolerances are argued next to each assertion.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from softevo import sim
from tests.sim._support import com_trajectory, frames, line, period_of, report, simulate, voxel_index
from tests.sim.scenes import actuated_scene

L_BAR, RHO_BAR, N_BAR = 0.01, 1000.0, 10
E_STIFF, E_SOFT = 1e7, 2.5e6


def series(e1: float, e2: float) -> float:
    """Modulus of a link of two half-voxels in series."""
    return e1 if e1 == e2 else 2 * e1 * e2 / (e1 + e2)


def _mixed_bar_field(axis: int = 0) -> np.ndarray:
    """Young's modulus of a bar of N_BAR voxels: the first half stiff, the second half soft."""
    e = np.where(np.arange(N_BAR) < N_BAR // 2, E_STIFF, E_SOFT)
    shape = [1, 1, 1]
    shape[axis] = N_BAR
    return e.reshape(shape)


def _bar_scene(forces: list, seconds: float, field: np.ndarray) -> dict:
    return {
        "voxel_size": L_BAR,
        "material": {"youngs_modulus": 1e6, "density": RHO_BAR},  # overridden by the field
        "youngs_modulus_field": field.tolist(),
        "environment": {"kind": "void"},
        "body": line(N_BAR, 0),
        "fixed": [[0, 0, 0]],
        "forces": forces,
        "duration": {"seconds": seconds},
        "self_collisions": False,
        "record": {"every": 100},
    }


def _link_moduli(field: np.ndarray) -> np.ndarray:
    e = field.ravel()
    return np.array([series(e[i], e[i + 1]) for i in range(len(e) - 1)])


def _settled(result, tail_from: float) -> np.ndarray:
    t, pos = frames(result)
    assert t[-1] > tail_from
    return pos[t >= tail_from].mean(axis=0) - pos[0]


def _bar_order(result) -> list[int]:
    index = voxel_index(result)
    return [index[(i, 0, 0)] for i in range(N_BAR)]


def test_axial_stretch_of_two_material_bar_is_sum_of_series_links():
    """Tip force F on a bar clamped at voxel 0: link j (stiffness E_j L, E_j the series
    modulus) stretches by F / (E_j L), so voxel k moves F / L * sum_{j < k} 1 / E_j.

    Strain <= 1e-3 in the soft half: nonlinear effects ~1e-3 of the answer; 1% tolerance
    (as the one-material axial test)."""
    field = _mixed_bar_field()
    e_link = _link_moduli(field)
    force = E_SOFT * L_BAR**2 * 1e-3
    result = simulate(_bar_scene([{"voxel": [N_BAR - 1, 0, 0], "force": [force, 0, 0]}], 0.4,
                                 field))
    got = _settled(result, 0.25)[_bar_order(result), 0]
    expected = np.concatenate([[0.0], np.cumsum(force / (e_link * L_BAR))])
    assert e_link[N_BAR // 2 - 1] == pytest.approx(4e6)  # the joint: 2 E1 E2 / (E1 + E2)
    report("materials.axial_two_materials", tip_expected_m=expected[-1], tip_got_m=got[-1],
           ratio=got[-1] / expected[-1])
    np.testing.assert_allclose(got, expected, rtol=0, atol=0.01 * expected[-1])


def _eb_deflection(x_nodes: np.ndarray, load: float, ei_segments: np.ndarray) -> np.ndarray:
    """Deflection at each node of a cantilever (clamped at x = 0) under a tip load, segment j
    spanning [j L, (j + 1) L] with bending stiffness EI_j: by the unit-load method,
    w(x_k) = sum_j integral over segment j of M(x) m_k(x) / EI_j dx, with M(x) = P (l - x)
    and m_k(x) = (x_k - x) for x < x_k. Each integral is of a quadratic, done exactly."""
    span = x_nodes[-1]
    out = np.zeros(len(x_nodes))
    for k, xk in enumerate(x_nodes):
        for j, ei in enumerate(ei_segments):
            a, b = j * L_BAR, min((j + 1) * L_BAR, xk)
            if b <= a:
                continue
            integrand = np.polynomial.Polynomial([span, -1]) * np.polynomial.Polynomial([xk, -1])
            anti = integrand.integ()
            out[k] += load * (anti(b) - anti(a)) / ei
    return out


def test_cantilever_of_two_materials_matches_euler_bernoulli_with_per_link_ei():
    """Tip load P across the bar: frame elements are exact for nodal loads, so the nodal
    deflections equal the piecewise Euler-Bernoulli solution with EI_j = E_j L^4 / 12 per
    link. Deflection ~1.5% of the span (geometric nonlinearity ~1e-4); 1.5% of the tip
    deflection as for the one-material cantilevers."""
    field = _mixed_bar_field()
    e_link = _link_moduli(field)
    load = 0.01
    result = simulate(_bar_scene([{"voxel": [N_BAR - 1, 0, 0], "force": [0, 0, load]}], 0.8,
                                 field))
    got = _settled(result, 0.5)[_bar_order(result), 2]
    x = np.arange(N_BAR) * L_BAR
    expected = _eb_deflection(x, load, e_link * L_BAR**4 / 12)
    uniform_soft = load * x[-1] ** 3 / (3 * E_SOFT * L_BAR**4 / 12)
    uniform_stiff = load * x[-1] ** 3 / (3 * E_STIFF * L_BAR**4 / 12)
    assert uniform_stiff < expected[-1] < uniform_soft
    report("materials.cantilever_two_materials", tip_expected_m=expected[-1],
           tip_got_m=got[-1], ratio=got[-1] / expected[-1])
    np.testing.assert_allclose(got, expected, rtol=0, atol=0.015 * expected[-1])


def test_two_mass_oscillator_with_combined_link():
    """Two free voxels of different moduli and densities, force F on the second, no damping.

    Link stiffness k = E_link L with E_link = 2 E_a E_b / (E_a + E_b); masses m = rho L^3.
    The stretch obeys u'' = F / m_b - k u (1 / m_a + 1 / m_b): u = u* (1 - cos wt) with
    w = sqrt(k / m_red), m_red = m_a m_b / (m_a + m_b), u* = F m_a / (k (m_a + m_b)); the
    centre of mass (mass-weighted) accelerates at F / (m_a + m_b).
    Symplectic Euler at w dt ~ 0.1 rad: period error ~ (w dt)^2 / 24 < 0.1%: 0.5% on the
    period, 1% on the amplitude (as the one-material oscillator tests)."""
    L = 0.05
    e_a, e_b, rho_a, rho_b = 1e6, 3e5, 1200.0, 400.0
    force = 2.0
    scene = {
        "voxel_size": L,
        "material": {"damping_bond": 0.0, "damping_global": 0.0, "damping_collision": 0.0},
        "youngs_modulus_field": [[[e_a]], [[e_b]]],
        "density_field": [[[rho_a]], [[rho_b]]],
        "environment": {"kind": "void"},
        "body": line(2),
        "forces": [{"voxel": [1, 0, 0], "force": [force, 0.0, 0.0]}],
        "self_collisions": False,
        "record": {"every": 1},
    }
    k = series(e_a, e_b) * L
    m_a, m_b = rho_a * L**3, rho_b * L**3
    m_red = m_a * m_b / (m_a + m_b)
    period = 2 * math.pi * math.sqrt(m_red / k)
    scene["duration"] = {"seconds": 30 * period}
    result = simulate(scene)
    # the step follows the stiffest link and the lightest voxel
    assert result.dt == pytest.approx(0.5 / (2 * math.pi * math.sqrt(k / min(m_a, m_b))))
    t, pos = frames(result)
    index = voxel_index(result)
    a, b = pos[:, index[(0, 0, 0)]], pos[:, index[(1, 0, 0)]]
    stretch = (b[:, 0] - a[:, 0]) - L
    got_period = period_of(t, stretch, crossings=5)
    u_star = force * m_a / (k * (m_a + m_b))
    amp = np.ptp(stretch)
    report("materials.two_mass_oscillator", period_expected_s=period, period_got_s=got_period,
           period_ratio=got_period / period, amplitude_expected_m=2 * u_star,
           amplitude_got_m=amp, amplitude_ratio=amp / (2 * u_star))
    assert got_period == pytest.approx(period, rel=0.005)
    assert amp == pytest.approx(2 * u_star, rel=0.01)
    tc, com = com_trajectory(result)
    accel = force / (m_a + m_b)
    expected = com[0, 0] + 0.5 * accel * tc**2
    assert np.all(np.abs(com[:, 0] - expected) <= accel * tc * result.dt + 1e-12)


def test_each_active_voxel_follows_its_own_frequency():
    """Void, no gravity: bar active(f1) - passive - active(f2). The gap between voxels 0 and 1
    is their rest length (s_0 + L) / 2 = L (1 + a/2 sin(2 pi f1 t)), the gap between 1 and 2
    L (1 + a/2 sin(2 pi f2 t)) (links 90 Hz vs actuation <= 3 Hz: quasi-static, lag constant).
    Periods from zero crossings of the recorded frames: 0.2%. The run lasts
    cycles / mean(f1, f2) seconds (to one step); the gap swings a L peak to peak (2%: the
    quasi-static response lags and shrinks by ~(f / f_link)^2 ~ 0.1%, bond damping more)."""
    L, amp, f1, f2, cycles = 0.05, 0.2, 2.0, 3.0, 10
    freq = [[[f1]], [[1.0]], [[f2]]]  # the passive voxel's value is unused
    result = simulate({
        "voxel_size": L,
        "material": {"youngs_modulus": 1e6, "density": 1200.0},
        "environment": {"kind": "void"},
        "body": [[[2]], [[1]], [[2]]],
        "actuation": {"frequency": 7.0, "amplitude": amp},  # overridden by the field
        "frequency_field": freq,
        "duration": {"cycles": cycles},
        "self_collisions": False,
        "record": {"every": 5},
    })
    expected_seconds = cycles / ((f1 + f2) / 2)
    assert abs(result.simulated_seconds - expected_seconds) <= result.dt
    t, pos = frames(result)
    index = voxel_index(result)
    x = [pos[:, index[(i, 0, 0)], 0] for i in range(3)]
    gaps = [x[1] - x[0], x[2] - x[1]]
    figures = {"seconds_expected": expected_seconds, "seconds_got": result.simulated_seconds}
    for gap, f, name in zip(gaps, (f1, f2), ("f1", "f2"), strict=True):
        late = t > 0.25  # skip the start-up transient
        got = period_of(t[late], gap[late], crossings=5)
        figures[f"{name}_period_expected_s"] = 1 / f
        figures[f"{name}_period_got_s"] = got
        figures[f"{name}_ptp_ratio"] = np.ptp(gap[late]) / (amp * L)
        assert got == pytest.approx(1 / f, rel=0.002)
        assert np.ptp(gap[late]) == pytest.approx(amp * L, rel=0.02)
    report("materials.frequency_field", **figures)


def test_actuation_step_cap_uses_the_highest_frequency():
    """A soft robot (stable step ~4 ms) actuated at up to 8 Hz: dt = 1 / (2000 x 8 Hz)."""
    result = sim.simulate({
        "material": {"youngs_modulus": 1e3},
        "body": [[[2]], [[2]], [[1]]],
        "frequency_field": [[[1.0]], [[8.0]], [[50.0]]],  # 50 Hz on a passive voxel: unused
        "duration": {"seconds": 0.01},
    })
    assert result.dt == 1.0 / (8.0 * 2000)


def _random_scene(env: str, seed: int) -> dict:
    rng = np.random.default_rng(seed)
    body = rng.choice([0, 1, 2], size=(4, 4, 3), p=[0.2, 0.3, 0.5])
    body[2, 2, 1] = 2
    return actuated_scene(body, rng, env, cycles=2, every=25, density=900.0)


def _assert_identical(a, b):
    da, db = a.to_dict(), b.to_dict()
    assert da.keys() == db.keys()
    for key in da:
        if isinstance(da[key], (list, dict)):
            va = da[key] if isinstance(da[key], list) else list(da[key].values())
            vb = db[key] if isinstance(db[key], list) else list(db[key].values())
            for x, y in zip(va, vb, strict=True):
                assert np.array_equal(np.asarray(x), np.asarray(y)), key
        else:
            assert da[key] == db[key], key


@pytest.mark.parametrize("env", ["land", "water", "void"])
def test_uniform_fields_are_bit_identical_to_scalars(env):
    """Fields holding the scalar everywhere give exactly the scalar scene's Result, frames
    included (self-collisions on, actuated); the fields override the scalars."""
    plain = _random_scene(env, 3)
    shape = np.asarray(plain["body"]).shape
    fielded = dict(plain, material={"youngs_modulus": 3e6, "density": 50.0},
                   actuation={"frequency": 1.0, "amplitude": 0.5},
                   youngs_modulus_field=np.full(shape, 1e5).tolist(),
                   density_field=np.full(shape, 900.0).tolist(),
                   frequency_field=np.full(shape, 4.0).tolist())
    a, b = sim.simulate_many([plain, fielded])
    assert a.stable and a.frames is not None
    _assert_identical(a, b)
    report(f"materials.uniform_bit_identical.{env}", frames=len(a.frames["t"]), identical=True)


def test_mixed_materials_keep_the_mass_weighted_centre_of_mass_in_void():
    """Internal forces are equal and opposite for any materials, so with global damping off
    (its drag against the world differs voxel by voxel) the mass-weighted centre of mass
    cannot move, however the robot folds (self-collisions on). Round-off: 1e-9 L."""
    scene = _random_scene("void", 5)
    rng = np.random.default_rng(5)
    shape = np.asarray(scene["body"]).shape
    scene["material"] = {"damping_global": 0.0}
    scene["youngs_modulus_field"] = (10 ** rng.uniform(4, 5.5, shape)).tolist()
    scene["density_field"] = rng.uniform(300, 3000, shape).tolist()
    scene["frequency_field"] = rng.uniform(2, 6, shape).tolist()
    result = simulate(scene)
    t, com = com_trajectory(result)
    _, pos = frames(result)
    drift = np.abs(com - com[0]).max() / 0.05
    moved = np.abs(pos[-1] - pos[0]).max() / 0.05
    report("materials.com_void_mixed", com_drift_L=drift, max_voxel_motion_L=moved)
    assert moved > 0.05
    assert drift < 1e-9


@pytest.mark.parametrize(("field", "value", "message"), [
    ("youngs_modulus_field", -3.0, "youngs_modulus_field: must be > 0 at [1, 0, 0] (got -3.0)"),
    ("density_field", 0.0, "density_field: must be > 0 at [1, 0, 0] (got 0.0)"),
    ("frequency_field", float("inf"), "frequency_field: must be finite at [1, 0, 0] (got inf)"),
    ("density_field", float("nan"), "density_field: must be finite at [1, 0, 0] (got nan)"),
])
def test_field_values_are_checked_at_present_voxels(field, value, message):
    body = [[[1, 0]], [[2, 0]]]
    values = [[[1.0, -5.0]], [[value, -5.0]]]  # the -5 sit at empty voxels: ignored
    with pytest.raises(sim.SceneError) as err:
        sim.parse_scene({"body": body, field: values})
    assert str(err.value) == message


@pytest.mark.parametrize(("values", "start"), [
    ([[[1.0]]], "youngs_modulus_field: shape [1, 1, 1] differs from body [2, 1, 2]"),
    ([[[1.0, "a"]], [[1.0, 1.0]]], "youngs_modulus_field: must be a nested list"),
    ([1.0, 2.0], "youngs_modulus_field: must be 3-D"),
])
def test_field_shape_and_type_errors(values, start):
    with pytest.raises(sim.SceneError) as err:
        sim.parse_scene({"body": [[[1, 0]], [[2, 0]]], "youngs_modulus_field": values})
    assert str(err.value).startswith(start)


def test_values_at_empty_voxels_are_ignored():
    body = [[[1, 0]], [[2, 0]]]
    scene = sim.parse_scene({"body": body, "youngs_modulus_field": [[[2e5, -1]], [[3e5, 0]]],
                             "frequency_field": [[[9.0, -1]], [[4.0, 0]]],
                             "duration": {"cycles": 8}})
    assert scene.youngs_modulus_field.tolist() == [[[2e5, 0]], [[3e5, 0]]]
    assert scene.duration_seconds == 2.0  # 8 cycles at the active voxel's 4 Hz
