"""The switches of the paper's engine's model (``"model": "voxcad-land-water"``, docs/fidelity.md),
each against a slow obvious version or a closed-form expectation:

- ``collision_horizon``: the voxels a voxel never touches, against a breadth-first walk;
- ``drag`` "mesh": the surface mesh's triangles against the lattice's exposed faces, and the
  mesh drag against the face drag where the two must agree exactly (one rigid voxel);
- ``rotation_damping``: the angular decay rate scales by the factor;
- ``actuation_clock`` / ``actuation_start``: the phase a voxel's sine reads, the settling;
- ``distance`` "3d" and ``min_steps_per_cycle``: the fitness and the step.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np
import pytest

from softevo import sim
from softevo.sim import kernels, system
from softevo.sim.scene import SceneError, parse_scene


def _random_body(seed: int, shape=(5, 5, 4), fill=0.6) -> np.ndarray:
    rng = np.random.default_rng(seed)
    body = (rng.random(shape) < fill).astype(int) * rng.integers(1, 3, shape)
    return system.largest_component(body)


def _walk(nbr: np.ndarray, start: int, hops: int) -> set[int]:
    seen, queue = {start: 0}, deque([start])
    while queue:
        v = queue.popleft()
        if seen[v] == hops:
            continue
        for w in nbr[v]:
            if w >= 0 and w not in seen:
                seen[w] = seen[v] + 1
                queue.append(w)
    return set(seen) - {start}


@pytest.mark.parametrize("hops", [1, 2, 3, 5])
def test_nearby_matches_a_breadth_first_walk(hops):
    for seed in range(4):
        body = _random_body(seed)
        robot = system.build_robot(parse_scene({"body": body.tolist()}))
        near = system.nearby(robot.nbr, hops)
        for v in range(len(robot.nbr)):
            assert {int(w) for w in near[v] if w >= 0} == _walk(robot.nbr, v, hops)


def test_collision_pairs_skip_every_pair_within_the_horizon():
    """A U whose arms stand 2 voxels apart: its tips are 10 bond hops apart. Horizons of 1 and
    3 let close arm voxels collide; a horizon of 10 leaves no pair; the candidate list holds
    exactly the close surface pairs more than the horizon apart (brute force)."""
    body = np.zeros((3, 1, 5), int)
    body[0, 0, :] = 1
    body[:, 0, 0] = 1
    body[2, 0, :] = 1
    for hops in (1, 3, 10):
        scene = parse_scene({"body": body.tolist(), "model_options": {"collision_horizon": hops}})
        robot = system.build_robot(scene)
        pos = robot.pos.copy()
        near = system.nearby(robot.nbr, hops)
        reach = 2.5 * scene.voxel_size
        pairs = np.zeros((200, 2), np.int64)
        count = kernels.collision_pairs(robot.surface, np.ascontiguousarray(pos.T), near, reach,
                                        pairs, np.zeros(len(pos), np.int64))
        got = {tuple(sorted(p)) for p in pairs[:count].tolist()}
        want = set()
        for a in robot.surface:
            far = _walk(robot.nbr, int(a), hops)
            for b in robot.surface:
                if a < b and int(b) not in far and np.linalg.norm(pos[a] - pos[b]) < reach:
                    want.add((int(a), int(b)))
        assert got == want
        assert bool(got) == (hops < 10)


def test_surface_mesh_covers_the_exposed_faces_with_outward_triangles():
    for seed in range(3):
        body = _random_body(seed)
        scene = parse_scene({"body": body.tolist(), "environment": {"kind": "water"},
                             "model": "voxcad-land-water"})
        robot = system.build_robot(scene)
        L = scene.voxel_size
        idx = robot.voxels
        lookup = -np.ones(body.shape, int)
        lookup[tuple(idx.T)] = np.arange(len(idx))
        # vertex positions at rest: the lattice corners, from the voxels that share them
        corners = np.array([[(c >> 2) & 1, (c >> 1) & 1, c & 1] for c in range(8)])
        points = np.zeros((len(robot.mesh_vert), 3))
        for k, row in enumerate(robot.mesh_vert):
            codes = row[row >= 0]
            spots = {tuple(idx[c >> 3] + corners[c & 7]) for c in codes}
            assert len(spots) == 1 and 1 <= len(codes) <= 7  # one lattice corner, not interior
            points[k] = np.array(spots.pop()) * L
            # every voxel whose cell has this corner is listed
            point = np.array(tuple(idx[codes[0] >> 3] + corners[codes[0] & 7]))
            owners = sum(1 for c in corners if np.all(point - c >= 0)
                         and np.all(point - c < body.shape) and lookup[tuple(point - c)] >= 0)
            assert owners == len(codes)
        exposed = int((robot.nbr < 0).sum())
        assert len(robot.mesh_face) == 2 * exposed
        area = np.zeros(len(idx))
        for a, b, c, v in robot.mesh_face:
            n = np.cross(points[b] - points[a], points[c] - points[a])
            area[v] += 0.5 * np.linalg.norm(n)
            centre = (points[a] + points[b] + points[c]) / 3
            assert np.dot(n, centre - robot.pos[v]) > 0  # outward
        np.testing.assert_allclose(area, (robot.nbr < 0).sum(axis=1) * L * L, rtol=1e-12)


def _coasting_voxel(drag: str) -> dict:
    return {"body": [[[1]]], "environment": {"kind": "water"}, "model": "voxcad-land-water",
            "model_options": {"drag": drag}, "initial_velocity": [0.3, -0.2, 0.1],
            "duration": {"seconds": 0.05}, "record": {"every": 50}}


def test_mesh_drag_equals_face_drag_on_one_rigid_voxel():
    """One voxel: its mesh is its own six faces, so the two drag models must give the same
    motion (to rounding)."""
    mesh, faces = sim.simulate(_coasting_voxel("mesh")), sim.simulate(_coasting_voxel("faces"))
    assert np.linalg.norm(mesh.displacement) > 1e-3
    np.testing.assert_allclose(mesh.frames["positions"], faces.frames["positions"],
                               rtol=0, atol=1e-12)


def test_mesh_drag_slows_a_coasting_bar_as_the_drag_law_says():
    """A rigid 4-voxel bar coasting along x in water: the front and back triangles (area L^2
    each end... only the front moves into the fluid) decelerate it as m dv/dt = -c A v^2,
    v(t) = v0 / (1 + c A v0 t / m)."""
    L, rho, v0, T = 0.05, 1200.0, 0.2, 0.2
    scene = {"body": [[[1]], [[1]], [[1]], [[1]]], "environment": {"kind": "water"},
             "model": "voxcad-land-water", "initial_velocity": [v0, 0, 0],
             "material": {"damping_global": 0.0, "youngs_modulus": 1e7, "density": rho},
             "duration": {"seconds": T}}
    result = sim.simulate(scene)
    c = 0.5 * 1000.0 * 1.5
    m = 4 * rho * L**3
    k = c * L * L / m
    want = math.log(1 + k * v0 * T) / k  # distance: integral of v(t)
    assert result.displacement[0] == pytest.approx(want, rel=2e-3)


def test_rotation_damping_scales_the_angular_decay():
    """The angular global damping coefficient is the factor times 2 zeta sqrt(I E L^3), and a
    spinning bonded pair in void slows accordingly. Its voxels' spin is damped by it, its
    orbit by the linear damping (coupled through the bond): with f = 10 the rigid-pair decay
    rate 2 zeta sqrt(E L / m) (1/2 + f / sqrt 6) / (5/6) is 6.6x that of f = 1, and the engine
    must show at least half that ratio over the first milliseconds."""
    coeff, decay = {}, {}
    for factor in (1.0, 10.0):
        scene = {"body": [[[1]], [[1]]], "environment": {"kind": "void"},
                 "material": {"damping_global": 0.05, "damping_bond": 0.0},
                 "initial_angular_velocity": [0, 0, 2.0], "duration": {"seconds": 0.005},
                 "record": {"every": 1}, "model_options": {"rotation_damping": factor}}
        coeff[factor] = system.build_robot(parse_scene(scene)).vconst[0, system.V_CGANG]
        result = sim.simulate(scene)
        t, pos = result.frames["t"], result.frames["positions"]
        rel = pos[:, 1] - pos[:, 0]
        turned = np.unwrap(np.arctan2(rel[:, 1], rel[:, 0]))
        decay[factor] = 2.0 * (t[-1] - t[0]) - (turned[-1] - turned[0])  # lag behind a free spin
    assert coeff[10.0] == pytest.approx(10 * coeff[1.0], rel=1e-12)
    assert decay[1.0] > 0
    assert decay[10.0] > 3.3 * decay[1.0]


def test_absolute_clock_advances_each_phase_by_the_settling_time():
    body = [[[2, 2]]]
    phase = [[[0.3, 1.1]]]
    base = {"body": body, "phase": phase, "settle_seconds": 0.25,
            "actuation": {"frequency": 2.0}}
    settled = system.build_robot(parse_scene(base))
    absolute = system.build_robot(parse_scene(
        {**base, "model_options": {"actuation_clock": "absolute"}}))
    dt = absolute.fparams[system.F_DT]
    start = absolute.iparams[system.I_ACT_START]
    assert start == absolute.iparams[system.I_SETTLE_STEPS] > 0
    np.testing.assert_allclose(absolute.phase - settled.phase, 2 * math.pi * 2.0 * start * dt,
                               rtol=1e-12)
    begun = system.build_robot(parse_scene({**base, "model_options": {"actuation_start": "start"}}))
    assert begun.iparams[system.I_ACT_START] == 0


def test_actuation_start_moves_the_body_while_it_settles():
    body = np.ones((3, 3, 2), int)
    body[:, :, 1] = 2
    base = {"body": body.tolist(), "environment": {"kind": "void"}, "settle_seconds": 0.1,
            "duration": {"seconds": 0.0}, "record": {"every": 20}}
    still = sim.simulate(base)
    moving = sim.simulate({**base, "model_options": {"actuation_start": "start"}})
    spread = np.ptp(still.frames["positions"][:, :, 2], axis=0).max()
    assert spread < 1e-12  # nothing actuates while settling
    assert np.ptp(moving.frames["positions"][:, :, 2], axis=0).max() > 1e-3


def test_3d_distance_and_step_floor():
    body = np.ones((3, 2, 2), int)
    body[0] = 2
    scene = {"body": body.tolist(), "duration": {"cycles": 2}, "settle_seconds": 0.05,
             "material": {"youngs_modulus": 1e4}}
    plain = sim.simulate(scene)
    assert plain.distance == pytest.approx(np.hypot(*plain.displacement[:2]) / 0.05)
    solid = sim.simulate({**scene, "model_options": {"distance": "3d"}})
    assert solid.distance == pytest.approx(np.linalg.norm(solid.displacement) / 0.05)
    floor = system.build_robot(parse_scene(scene)).fparams[system.F_DT]
    free = system.build_robot(parse_scene(
        {**scene, "model_options": {"min_steps_per_cycle": 0}})).fparams[system.F_DT]
    assert floor == pytest.approx(1 / (3.0 * 2000))
    assert free == pytest.approx(system.stable_dt(0.05, 1200.0, 1e4, 0.5)) and free > floor


def test_model_defaults_and_errors():
    paper = parse_scene({"body": [[[2]]], "model": "voxcad-land-water"})
    assert (paper.dt_fraction, paper.actuation.amplitude) == (0.7, 0.14)
    assert paper.options.rotation_damping == 10 and paper.options.collision_horizon == 3
    assert sim.models.defaults("voxcad-land-water")["model_options"]["drag"] == "mesh"
    plain = parse_scene({"body": [[[2]]]})
    assert (plain.model, plain.dt_fraction, plain.actuation.amplitude) == ("voxelyze-2", 0.5, 0.39)
    for bad, start in (({"model": "voxcad"}, "model:"),
                       ({"model_options": {"drag": "air"}}, "model_options.drag:"),
                       ({"model_options": {"collision_horizon": 0}}, "model_options.collision_horizon:"),
                       ({"model_options": {"speed": 1}}, "model_options.speed:")):
        with pytest.raises(SceneError) as err:
            parse_scene({"body": [[[1]]], **bad})
        assert str(err.value).startswith(start)


def test_voxcad_contact_repels_spheres_of_one_and_a_half_voxels_undamped():
    """The fork's contact (``contact`` "voxcad"): two voxels 1.2 L apart overlap as spheres of
    1.5 L diameter by 0.3 L and repel with a1 = E L times it, whatever their relative speed;
    Voxelyze 2's touching cubes do not touch yet."""
    L, E = 0.05, 1e5
    pos = np.array([[0.0, 0.0, 0.0], [1.2 * L, 0.0, 0.0]])
    mom = np.array([[0.0, 0.0, 0.0], [-0.01, 0.0, 0.0]])  # closing: damping would add force
    size = np.full(2, L)
    vconst = np.zeros((2, system.N_VCONST))
    vconst[:, system.V_KFLOOR] = 2 * E * L
    vconst[:, system.V_CCOLL] = 3.0
    vconst[:, system.V_INV_MASS] = 1 / (1200 * L**3)
    pairs = np.array([[0, 1]])
    for reach, stiff, damp, want in ((0.5, 1.0, 1.0, 0.0), (0.75, 0.5, 0.0, E * L * 0.3 * L)):
        force = np.zeros((3, 2))  # the kernels' rows by component
        kernels.contact_forces_kernel(1, pairs, pos.T.copy(), mom.T.copy(), size, vconst, force,
                                      reach, stiff, damp)
        force = force.T
        assert force[1, 0] == pytest.approx(want, rel=1e-12, abs=1e-15)
        assert force[0, 0] == -force[1, 0]
    robot = system.build_robot(parse_scene({"body": [[[1]]], "model": "voxcad-land-water"}))
    assert tuple(robot.fparams[[system.F_CONTACT_REACH, system.F_CONTACT_STIFF,
                                system.F_CONTACT_DAMP]]) == (0.75, 0.5, 0.0)


def test_a_sliding_voxel_stops_where_coulomb_friction_says():
    """The fork's friction rule: a voxel resting on the floor, launched at v0 along x, slides
    (it moves, so kinetic friction acts), is slowed by mu_k m g, stops dead once mu_k N dt
    would take all its momentum, after v0^2 / (2 mu_k g), and then stays put."""
    rule = "voxcad"
    v0, mu_k, g = 0.2, 0.5, 9.81
    scene = {"body": [[[1]]], "material": {"youngs_modulus": 1e5, "damping_global": 0.0},
             "initial_velocity": [v0, 0, 0],
             # initial_offset: at rest on the floor
             "initial_offset": [0, 0, -1200 * 0.05**3 * g / (2 * 1e5 * 0.05)],
             "duration": {"seconds": 0.1}, "model_options": {"friction": rule},
             "record": {"every": 20}}
    result = sim.simulate(scene)
    want = v0 * v0 / (2 * mu_k * g)
    assert result.displacement[0] == pytest.approx(want, rel=0.03)
    x = result.frames["positions"][:, 0, 0]
    assert x[-1] == x[-2]  # at rest


def test_nearby_rows_ascend_with_their_pads_at_the_end():
    """``substeps.listed`` stops at the first entry past the voxel it looks for, so every row
    of ``near`` ascends and its -1 pads come last, for one hop (the face neighbours) as for
    more; and ``listed`` agrees with set membership on every pair."""
    body = np.ones((3, 4, 3), int)
    body[1, 1:3, 1] = 0
    robot = system.build_robot(parse_scene({"body": body.tolist()}))
    for hops in (1, 2, 3):
        near = system.nearby(robot.nbr, hops)
        for v, row in enumerate(near):
            kept = row[row >= 0]
            assert np.all(np.diff(kept) > 0) and np.all(row[len(kept):] == -1)
            members = {int(w) for w in kept}
            assert members == _walk(robot.nbr, v, hops)
            flat, width = near.reshape(-1), near.shape[1]
            for j in range(len(near)):
                assert kernels.listed(flat, width, v, j) == (j in members)
