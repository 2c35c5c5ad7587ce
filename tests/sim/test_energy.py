"""The energy audit (``sim.energy``, ``softevo simulate --energy``; docs/physics.md "Energy").

- Closed forms: a voxel falling freely keeps its mechanical energy to the step's own term
  (E + S is what semi-implicit Euler keeps, S = dt/2 sum F . v: its tolerance); a link
  that breathes in the void without damping takes exactly the work its actuators put in; a
  single actuated voxel on the floor; a passive cube settling loses energy, all of it to
  dissipation.
- Random robots and robots of evolution's CPPN encoding, on land and in water, in both
  models: at no step does the mechanical energy gain more than the actuators' work plus the
  step's tolerance, and what the audit cannot account for is the beam's non-gradient loads
  and the frame switches it measures.
- The quickstart's jumping cube (a stored robot of ``softevo run --env land --stiffness 1
  --population 8 --generations 8 --workspace 5,5,5 --cycles 4``): a catapult, its numbers.
- The beam's moment on a link's negative end is not the gradient of its energy when the
  ends are not L apart (Voxelyze 2's beam; the audit's ``link_nonconservative``).
- The audited run is the engine's: the same final positions as the numba engine's (to the
  bit) and the cuda engine's (to its agreement with numba).
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from softevo import sim
from softevo.evolution.genotype import EncodingConfig, random_viable
from softevo.sim import energy, physics
from tests.sim._support import report

L, E, RHO = 0.05, 1e5, 1000.0
UNDAMPED = {"damping_bond": 0.0, "damping_global": 0.0, "damping_collision": 0.0}
JUMP_SCENE = Path(__file__).with_name("quickstart_jump.json")
WORST: dict[str, tuple[float, str]] = {}


def _scene(body, env: str = "land", seconds: float = 0.3, amplitude: float = 0.0,
           damped: bool = True, **extra) -> dict:
    material = {"youngs_modulus": E, "density": RHO, **({} if damped else UNDAMPED)}
    return {"voxel_size": L, "material": material, "environment": {"kind": env},
            "body": np.asarray(body).tolist(), "duration": {"seconds": seconds},
            "actuation": {"frequency": 4.0, "amplitude": amplitude}, **extra}


def _spring_work(m: dict) -> float:
    """The actuators' work through the springs (links, floor, contacts, the step's term):
    all of it but the dampers' share."""
    parts = m["actuator_work_parts"]
    return parts["links"] + parts["floor"] + parts["contacts"] + parts["integrator"]


def _check_balance(m: dict, name: str, share: float) -> None:
    """No energy from nowhere beyond the step's tolerance (at any step, ``peak_excess``; at
    the end, the mechanical change against the work put in), less ``share`` of the energy
    turned over (the springs' work and the dissipation) for the penalty contacts' onsets
    within a step; and what the audit does not account for, beyond the integrator's term,
    is what it measures apart (the beam's non-gradient loads, the frame switches) to
    ``share`` of it too."""
    scale = abs(_spring_work(m)) + m["dissipated_known"] + m["tolerance"] + 1e-12
    assert m["peak_excess"] <= share * scale, m
    assert (m["mechanical_change"]
            <= m["actuator_work"] + m["external_work"] + m["tolerance"] + share * scale)
    residual = (m["unaccounted"] - m["integrator_term"] + m["link_nonconservative"]
                + m["frame_switches"])
    assert abs(residual) <= share * scale, m
    for key, value in (("residual", abs(residual) / scale),
                       ("unaccounted", abs(m["unaccounted"]) / scale),
                       ("gain_over_work", m["mechanical_change"] / max(m["actuator_work"], 1e-12)),
                       ("gain_over_spring_work", m["mechanical_change"] / max(_spring_work(m), 1e-12)),
                       ("excess", m["peak_excess"] / scale)):
        if value > WORST.get(key, (-math.inf, ""))[0]:
            WORST[key] = (value, name)
    report("energy audit: the worst ratios (of the energy turned over; robot)", **{
        key: f"{value:.3g} ({where})" for key, (value, where) in WORST.items()})


def test_free_fall_keeps_mechanical_energy_to_the_steps_term():
    """A voxel falling 0.2 s in the air without damping: the mechanical energy changes by
    exactly minus the integrator's term (E + S is kept to rounding), which is
    dt/2 m g v at the end (S at the start is 0): the tolerance derived from dt."""
    scene = _scene([[[1]]], damped=False, seconds=0.2, initial_offset=[0.0, 0.0, 0.5])
    m = energy.audit(scene).summary()
    mass, g = RHO * L**3, 9.81
    fallen = m["mechanical_change_parts"]["gravitational"]
    n, dt = m["steps"], m["dt"]
    assert fallen == pytest.approx(-mass * g * g * dt**2 * n * (n + 1) / 2, rel=1e-9)  # the scheme's
    assert abs(m["mechanical_change"] + m["integrator_term"]) <= 1e-12 * abs(fallen)
    assert abs(m["mechanical_change"]) <= m["tolerance"] * (1 + 1e-9)
    assert m["tolerance"] == pytest.approx(0.5 * dt * mass * g * (g * n * dt), rel=1e-9)
    assert m["actuator_work"] == 0.0
    assert m["dissipated_known"] == pytest.approx(0.0, abs=1e-12 * abs(fallen))


def test_breathing_link_takes_exactly_the_actuators_work():
    """Two active voxels in the void, in phase, no damping: one linear spring whose rest
    length changes. The energy that semi-implicit Euler keeps (E + S) changes by exactly the
    actuators' work (the rest length's change at fixed positions, of E and of S)."""
    scene = _scene([[[2]], [[2]]], env="void", damped=False, seconds=0.5, amplitude=0.3)
    m = energy.audit(scene).summary()
    assert m["actuator_work_parts"]["links"] != 0.0
    assert m["unaccounted"] - m["integrator_term"] == pytest.approx(0.0, abs=1e-9 * m["tolerance"]
                                                                    + 1e-15)
    assert m["link_nonconservative"] == pytest.approx(0.0, abs=1e-15)
    _check_balance(m, "breathing link", 1e-9)


def test_single_actuated_voxel_on_the_floor():
    """One active voxel on the floor, no damping: its actuator works against the floor's
    spring only; the balance holds to the floor contact's on/off steps."""
    scene = _scene([[[2]]], damped=False, seconds=1.0, amplitude=0.3)
    m = energy.audit(scene).summary()
    assert m["actuator_work_parts"]["links"] == 0.0
    assert m["actuator_work_parts"]["floor"] != 0.0
    assert abs(m["unaccounted"]) <= 0.05 * abs(_spring_work(m)) + m["tolerance"]
    _check_balance(m, "actuated voxel", 0.05)


def test_passive_cube_settling_loses_energy_to_dissipation():
    """A passive 2^3 cube dropped from 1 cm: its mechanical energy falls, every joule of it
    dissipated (damping, floor, friction), to 2e-3 of the loss (the floor contacts' onsets)."""
    scene = _scene(np.ones((2, 2, 2)), seconds=0.6, initial_offset=[0.0, 0.0, 0.01])
    audit = energy.audit(scene)
    m = audit.summary()
    assert m["mechanical_change"] < 0.0
    assert m["dissipated_known"] > 0.0 and m["actuator_work"] == 0.0
    assert abs(m["unaccounted"]) <= 2e-3 * m["dissipated_known"]
    assert np.all(audit.excess() <= 2e-3 * m["dissipated_known"])
    _check_balance(m, "settling cube", 2e-3)


def _cppn_scenes(model: str, env: str) -> list[dict]:
    """Three robots of evolution's CPPN encoding (random newcomers with active voxels, a 4^3
    workspace) and one random body, 0.3-0.4 s each, self-collisions on."""
    config = EncodingConfig(workspace=(4, 4, 4))
    scenes, seed = [], 0
    while len(scenes) < 3:
        _, phenotype = random_viable(np.random.default_rng(seed), config)
        seed += 1
        if phenotype.active_share < 0.2:
            continue
        scene = phenotype.to_scene(env, E, cycles=2, model=model, max_seconds=0.3,
                                   settle_seconds=0.1 if env == "land" else 0.0)
        scenes.append({**scene, "self_collisions": True})
    rng = np.random.default_rng(7)
    body = (rng.random((3, 3, 2)) < 0.8).astype(int) * rng.integers(1, 3, (3, 3, 2))
    body[1, 1, 0] = 2
    scenes.append({**_scene(body, env=env, seconds=0.3, amplitude=0.3,
                            phase=rng.uniform(-math.pi, math.pi, body.shape).tolist(),
                            self_collisions=True), "model": model})
    return scenes


@pytest.mark.parametrize("model", ["voxelyze-2", "voxcad-land-water"])
@pytest.mark.parametrize("env", ["land", "water"])
def test_no_energy_from_nowhere_on_random_and_evolved_robots(model, env):
    """At no step of any robot does the mechanical energy gain more than the work put in
    plus the step's tolerance; the unaccounted energy is the beam's non-gradient loads and
    the frame switches, to 1% of the springs' work."""
    for k, scene in enumerate(_cppn_scenes(model, env)):
        audit = energy.audit(scene)
        assert audit.stable
        m = audit.summary()
        assert m["actuator_work"] > 0.0
        _check_balance(m, f"{model} {env} robot {k}", 1e-2)


def test_the_quickstarts_jumping_cube_is_a_catapult():
    """The quickstart's best robot (124 voxels, all active, 1 MPa, amplitude 0.39) leaves the
    floor by more than its height within 0.17 s of actuation. The actuators store about
    1.7 kJ in the links in the step in which actuation starts (every size jumps to
    L (1 + a sin phase)); the mechanical gain at the top of the jump is a tenth of it, and
    the energy the audit cannot account for is the beam's non-gradient work and the frame
    switches, within 0.5 J."""
    scene = json.loads(JUMP_SCENE.read_text())
    scene["duration"] = {"seconds": 0.2}
    audit = energy.audit(scene)
    s, t = audit.series, audit.column("t")
    start = int(round(scene["settle_seconds"] / audit.dt)) - 1  # before the switch-on step
    top = start + int(np.argmax(audit.column("com_z")[start:]))
    z = audit.column("com_z")
    assert z[start] == pytest.approx(0.125, abs=0.002)
    assert z[top] > 0.38 and t[top] - t[start] < 0.2
    at_top = s[top] - s[start]
    column = {name: at_top[energy.COLUMNS.index(name)] for name in energy.COLUMNS}
    stored = s[start + 1, energy.C_ELINK] - s[start, energy.C_ELINK]
    assert stored > 1000.0  # joules, in one step
    gain = audit.gain()[top] - audit.gain()[start]
    springs = sum(column[name] for name in ("actuator_links", "actuator_floor",
                                            "actuator_contacts", "actuator_integrator"))
    lift = column["gravitational"]
    assert lift > 40.0 and gain < 0.2 * springs
    assert np.all(audit.excess() <= 0.0)
    work = audit.actuator_work()[top] - audit.actuator_work()[start]
    dissipated = audit.dissipated()[top] - audit.dissipated()[start]
    unaccounted = work - gain - dissipated
    leak = column["link_nonconservative"]
    assert abs(unaccounted + leak + column["frame_switches"]) < 0.5
    assert abs(leak) < 0.3 * lift
    report("energy audit: the quickstart's jumping cube", com_start=z[start], com_top=z[top],
           seconds=t[top] - t[start], stored_at_switch_on=stored, spring_work=springs,
           gain=gain, lift=lift, leak=leak, frame_switches=column["frame_switches"],
           unaccounted=unaccounted)


def _loads_and_energy(theta_a: float, b: tuple, turn_b: float, rest: float):
    """One x link of the small-angle frame, voxel a at the origin turned by theta_a about z
    and voxel b at b turned by turn_b: the beam's energy (``energy.link_energy``' formula)
    and its loads (``physics.link_loads``)."""
    a1, a2 = E * L, E * L**3 / (12 * 1.4)
    b1, b2, b3 = E * L, E * L**2 / 2, E * L**3 / 6
    qa = (math.cos(theta_a / 2), 0.0, 0.0, math.sin(theta_a / 2))
    qb = (math.cos(turn_b / 2), 0.0, 0.0, math.sin(turn_b / 2))
    R, rx, ry, rz, ow, ox, oy, oz = physics.link_geometry(*qa, *qb, b[0], b[1], 0.0, 0)
    W, d, ey, ez, t1y, t1z, t2x, t2y, t2z, _ = physics.small_frame(R, 0, rx, ry, rz, ow, ox, oy,
                                                                    oz, rest)
    u = energy.link_energy.py_func(a1 * rest / L, a2, b1, b2, b3, d, ey, ez, t1y, t1z, t2x, t2y,
                                   t2z)
    return u, physics.link_loads(W, 1.0, rest, L, a1, a2, b1, b2, b3, d, ey, ez, t1y, t1z, t2x,
                                 t2y, t2z)


@pytest.mark.parametrize("stretch", [1.0, 1.3, 0.7])
def test_the_beams_moment_on_its_negative_end_takes_the_arm_L(stretch):
    """The beam's force on either end and its moment on the positive end are the gradient of
    its energy; its moment on the negative end differs from it by (r_x - L) F_y - r_y F_x
    (F the force on the positive end, r its offset): the moments balance the forces about
    an arm of L where the ends are r apart. Second order at the nominal size, first order
    in an actuated link's strain: the audit's ``link_nonconservative`` (docs/physics.md)."""
    rest = stretch * L
    b, turn, h = (1.01 * rest, 0.002), 0.01, 1e-7

    def u(theta=0.0, dx=0.0, dy=0.0, dturn=0.0):
        return _loads_and_energy(theta, (b[0] + dx, b[1] + dy), turn + dturn, rest)[0]

    fx, fy, fz, max_, may, maz, mbx, mby, mbz = _loads_and_energy(0.0, b, turn, rest)[1]
    assert -fx == pytest.approx(-(u(dx=h) - u(dx=-h)) / (2 * h), rel=1e-6)
    assert -fy == pytest.approx(-(u(dy=h) - u(dy=-h)) / (2 * h), rel=1e-6)
    assert mbz == pytest.approx(-(u(dturn=h) - u(dturn=-h)) / (2 * h), rel=1e-6)
    gradient = -(u(theta=h) - u(theta=-h)) / (2 * h)
    assert maz - gradient == pytest.approx((b[0] - L) * (-fy) - b[1] * (-fx), rel=1e-5, abs=1e-9)
    if stretch != 1.0:
        assert abs(maz - gradient) > 0.1 * abs(maz)


CUDA_AGREEMENT = """
import json, sys
from softevo import sim
from softevo.sim import energy
scene = json.loads(sys.argv[1])
result = sim.simulate(scene, engine="cuda")
print(json.dumps(energy.audit(scene, "cuda", result.final_positions).summary()))
"""


def test_the_audited_run_is_the_engines():
    """The audit steps the numba engine's own sub-steps: its final positions are the numba
    engine's to the bit, and the cuda engine's (numba-cuda's simulator, in a process of its
    own that sets it up before numba loads) to 1e-9 of the body's size."""
    scene = _scene(np.full((2, 2, 1), 2), seconds=0.006, amplitude=0.3,
                   phase=[[[0.0], [1.0]], [[2.0], [3.0]]])
    numba_result = sim.simulate(scene)
    m = energy.audit(scene, final_positions=numba_result.final_positions).summary()
    assert m["engine_agreement"] == 0.0
    done = subprocess.run([sys.executable, "-c", CUDA_AGREEMENT, json.dumps(scene)],
                          capture_output=True, text=True, timeout=600,
                          env={**os.environ, "NUMBA_ENABLE_CUDASIM": "1"})
    assert done.returncode == 0, done.stderr[-2000:]
    m = json.loads(done.stdout.strip().splitlines()[-1])
    assert m["engine"] == "cuda" and m["engine_agreement"] <= 1e-9 * 2 * L
