"""Each numba kernel against the slow, obvious NumPy/SciPy version on small cases."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from softevo import sim
from softevo.sim import kernels, system
from tests.sim import numpy_reference as ref

ENVS = {"land": 0, "water": 1, "void": 2}


def _robot(env: str, seed: int, shape=(3, 2, 2), mixed: bool = False, **extra):
    """A random robot; ``mixed``: random per-voxel Young's modulus (1e4..1e6 Pa) and density
    (600..2400 kg/m^3) fields. Returns the batch, its state, the rng, the materials of its
    voxels (E, rho) and the parsed scene."""
    rng = np.random.default_rng(seed)
    body = rng.choice([1, 2], size=shape)
    scene = {"body": body.tolist(), "phase": rng.uniform(0, 6.28, shape).tolist(),
             "environment": {"kind": env}, "material": {"youngs_modulus": 1e5},
             "self_collisions": False, "duration": {"seconds": 0.01}, **extra}
    if mixed:
        scene["youngs_modulus_field"] = (10 ** rng.uniform(4, 6, shape)).tolist()
        scene["density_field"] = rng.uniform(600, 2400, shape).tolist()
    parsed = sim.parse_scene(scene)
    robot = system.build_robot(parsed)
    batch, state = system.pack([robot])
    return batch, state, rng, ref.voxel_materials(parsed, batch), parsed


def _perturb(state, rng, angle: float, shift: float, speed: float):
    """Deform the lattice: random rotations up to ``angle`` rad, shifts, velocities."""
    L = 0.05
    state.pos[:] += rng.uniform(-shift, shift, state.pos.shape) * L
    for v in range(len(state.pos)):
        r = Rotation.from_rotvec(rng.uniform(-angle, angle, 3))
        state.quat[v] = ref.wxyz(r)
    state.lin_mom[:] = rng.normal(0, speed, state.lin_mom.shape)
    state.ang_mom[:] = rng.normal(0, speed * 1e-3, state.ang_mom.shape)


def _links(batch):
    return kernels.Links(batch.link_neg, batch.link_pos, batch.link_axis, batch.vlink,
                         batch.link_stiff, batch.link_damp)


def _work(batch, n, collide=False):
    return kernels.robot_work(n, _links(batch), int(batch.poff[-1]), batch.surface, batch.near,
                              collide, 0, np.zeros(0))


def _rows(work, first, count):
    """Rows ``first`` ... of the kernel's link buffer (tiles of LINK_TILE places), in the
    links' own order (the kernel keeps them by frame: ``work.link_id`` names the link at each
    place)."""
    m, tile = len(work.link_id), kernels.LINK_TILE
    tiles = work.link_buf.reshape(-1, kernels.LINK_ROWS, tile)
    rows = tiles.transpose(1, 0, 2).reshape(kernels.LINK_ROWS, -1)[first:first + count]
    assert not rows[:, m].any()  # the zero that link_sums reads for a face without a link
    out = np.empty((count, m))
    out[:, work.link_id] = rows[:, :m]
    return out


def _link_forces(batch, p, pos, quat, size, work, force, moment):
    """The link forces as the step computes them (``kernels.link_forces``: beams in their two
    runs, frame changes, per-voxel sums). The sums are also checked against a NumPy scatter
    of the per-link forces, and the kernel's places of the links against their voxels."""
    n = len(pos)  # pos, quat (n, 3), (n, 4); the kernels' rows by component (``take_robot``)
    body = system.State(np.ascontiguousarray(pos.T), np.ascontiguousarray(quat.T),
                        np.zeros((3, n)), np.zeros((3, n)))
    bad = kernels.link_forces(p, _links(batch), body, work)
    m = len(work.link_id)
    assert sorted(work.link_id) == list(range(m))
    ends = work.link_ends.reshape(2, m)
    np.testing.assert_array_equal(ends[0], batch.link_neg[work.link_id])
    np.testing.assert_array_equal(ends[1], batch.link_pos[work.link_id])
    small = _rows(work, kernels.ROW_MODE, 1)[0] >= 0
    assert small[work.link_id[:work.split[0]]].all() and not small[work.link_id[work.split[0]:]].any()
    faces = np.full(batch.vlink.shape, m)
    place = np.argsort(work.link_id)
    faces[batch.vlink < m] = place[batch.vlink[batch.vlink < m]]
    offsets = np.array([kernels.place(f) for f in faces.ravel()]).reshape(faces.shape)
    np.testing.assert_array_equal(work.vlink, offsets)
    out = _rows(work, kernels.ROW_OUT, kernels.LINK_OUT_ROWS)
    f, mo = np.zeros((n, 3)), np.zeros((n, 3))
    np.add.at(f, batch.link_neg, out[0:3].T)
    np.add.at(f, batch.link_pos, -out[0:3].T)
    np.add.at(mo, batch.link_neg, out[3:6].T)
    np.add.at(mo, batch.link_pos, out[6:9].T)
    np.testing.assert_allclose(force.T, f, rtol=1e-12, atol=1e-12 * np.abs(f).max())
    np.testing.assert_allclose(moment.T, mo, rtol=1e-12, atol=1e-12 * np.abs(mo).max())
    return bad


def _link_state(work, m):
    """The kernel's link state as the reference keeps it: small-angle flags, previous
    deformation (9, m), and whether that previous deformation exists."""
    state = _rows(work, kernels.ROW_STATE, kernels.LINK_STATE_ROWS)
    return state[9] >= 0, state[:9], state[9] != 0


@pytest.mark.parametrize("mixed", [False, True], ids=["one_material", "mixed_field"])
@pytest.mark.parametrize("angle,shift", [(0.01, 0.01), (0.4, 0.3), (1.2, 0.5)])
def test_link_forces_match_numpy(angle, shift, mixed):
    """Small-angle and large-angle link frames, with bond damping from a previous state;
    one material and a random per-voxel material field."""
    _check_link_forces(angle, shift, mixed, (3, 2, 2))


def test_link_forces_match_numpy_over_several_tiles():
    """A robot with more links than one tile of the kernel's link buffer holds, in both
    frames, links changing frame between the calls."""
    m = _check_link_forces(0.4, 0.3, True, (9, 9, 5))
    assert m > kernels.LINK_TILE


def _check_link_forces(angle, shift, mixed, shape):
    """Two calls of the link forces against the NumPy reference; returns the link count."""
    batch, state, rng, mats, scene = _robot("void", seed=3, mixed=mixed, shape=shape)
    _perturb(state, rng, angle, shift, 0.0)
    n = len(state.pos)
    work = _work(batch, n)
    size, force, moment = work[:3]
    size[:] = 0.05 * rng.uniform(0.8, 1.2, n)
    fp = batch.fparams[0]
    p = kernels.params(fp, batch.iparams[0])
    m = len(batch.link_neg)
    small_ref, prev_ref, valid_ref = (a.copy() for a in _link_state(work, m))
    for _ in range(2):  # the second call exercises the damping term
        bad = _link_forces(batch, p, state.pos, state.quat, size, work, force, moment)
        assert bad == 0
        f_ref, m_ref = ref.link_forces(batch, state.pos, state.quat, size, small_ref, prev_ref,
                                       valid_ref, fp, mats, scene)
        scale = np.abs(f_ref).max()
        small = _link_state(work, m)[0]
        np.testing.assert_array_equal(small, small_ref)
        np.testing.assert_allclose(_link_state(work, m)[1], prev_ref, rtol=1e-10, atol=1e-14)
        # the kernel's rotation-vector polynomial is accurate to 5e-14 relative (kernels.rotvec)
        np.testing.assert_allclose(force.T, f_ref, atol=1e-10 * scale)
        np.testing.assert_allclose(moment.T, m_ref, atol=1e-10 * scale * 0.05)
        state.pos[:] += rng.normal(0, 1e-5, state.pos.shape)
    if angle > 1:
        assert not small.all(), "large deformations must use the large-angle frame"
    return m


@pytest.mark.parametrize("mixed", [False, True], ids=["one_material", "mixed_field"])
@pytest.mark.parametrize("env", ["land", "water", "void"])
def test_trajectory_matches_numpy(env, mixed):
    """Whole steps: links, gravity, floor, friction, drag, integration, actuation off; one
    material and a random per-voxel material field."""
    batch, state, rng, mats, scene = _robot(env, seed=7, mixed=mixed,
                                            initial_velocity=[0.05, -0.02, 0.0])
    _perturb(state, rng, 0.05, 0.02, 2e-4)
    if env == "land":
        state.pos[:, 2] -= 0.002  # press into the floor so contact and friction act
    n = len(state.pos)
    work = _work(batch, n)
    size, _f, _m, static = work[:4]
    size[:] = 0.05
    fp = batch.fparams[0].copy()
    p, voxels, _links, mine = kernels.take_robot(batch, state, 0)
    theirs = [a.copy() for a in state]
    static_ref = static.copy()
    small_ref, prev_ref, valid_ref = (a.copy() for a in _link_state(work, len(batch.link_neg)))
    for _ in range(60):
        _link_forces(batch, p, mine.pos.T, mine.quat.T, size, work, _f, _m)
        kernels.voxel_update(p, voxels, mine, work)
        ref.step(batch, theirs, size, static_ref, small_ref, prev_ref, valid_ref, fp, ENVS[env],
                 mats, scene)
    np.testing.assert_array_equal(static, static_ref)
    np.testing.assert_allclose(mine.pos.T, theirs[0], atol=1e-10)  # rows by component
    np.testing.assert_allclose(mine.quat.T, theirs[1], atol=1e-8)
    np.testing.assert_allclose(mine.lin_mom.T, theirs[2], atol=1e-9 * np.abs(theirs[2]).max())


def expected_sizes(wave: str, angle: np.ndarray, flags: np.ndarray) -> np.ndarray:
    """Voxel sizes of the actuation test's robot (L 0.05, amplitude 0.3) at phase ``angle``."""
    if wave == "sine":
        w = np.sin(angle)
    elif wave == "square":
        w = np.tanh(8 * np.sin(angle)) / np.tanh(8)
    else:
        u = np.mod(angle / (2 * np.pi), 1.0)
        w = np.where(u < 0.2, np.cos(np.pi * u / 0.2), -np.cos(np.pi * (u - 0.2) / 0.8))
    active = (flags & system.FLAG_ACTIVE) > 0
    return np.where(active, 0.05 * (1 + 0.3 * w), 0.05)


@pytest.mark.parametrize("wave", ["sine", "square", "impulse"])
def test_actuation_matches_numpy(wave):
    batch, _state, rng, _mats, _scene = _robot("void", seed=1,
                                               actuation={"waveform": wave, "amplitude": 0.3})
    n = len(batch.flags)
    size = np.zeros(n)
    fp = batch.fparams[0]
    p = kernels.params(fp, batch.iparams[0])
    assert p.wave == system.WAVE_CODES[wave]
    assert p.freq_field == 0
    for t in rng.uniform(0, 2, 5):
        kernels.actuate_kernel(t, p, batch.flags, batch.cos_phase, batch.sin_phase,
                               batch.phase, batch.vconst, size)
        angle = fp[system.F_OMEGA] * t + batch.phase
        np.testing.assert_allclose(size, expected_sizes(wave, angle, batch.flags), rtol=1e-12)
    kernels.actuate_kernel(-0.1, p, batch.flags, batch.cos_phase, batch.sin_phase,
                           batch.phase, batch.vconst, size)
    assert np.all(size == 0.05), "no actuation while settling"


@pytest.mark.parametrize("hops", [1, 3])
def test_listed_is_membership_in_the_near_row(hops):
    """``listed`` (a binary search over a row ascending with -1 pads at its end) against the
    obvious test, j in the row, for every pair of a robot's voxels and for rows of every
    width from 0 to 9 of random members, compiled and plain."""
    from softevo.sim import substeps

    body = np.ones((4, 3, 3), int)
    body[1, 1, 1:] = 0
    robot = system.build_robot(sim.parse_scene({"body": body.tolist()}))
    near = system.nearby(robot.nbr, hops)
    n, width = near.shape
    flat = near.reshape(-1)
    for i in range(n):
        row = set(near[i][near[i] >= 0].tolist())
        got = [kernels.listed(flat, width, i, j) for j in range(-1, n + 1)]
        assert got == [j in row for j in range(-1, n + 1)]
    rng = np.random.default_rng(3)
    for width in range(10):
        for _ in range(20):
            members = np.sort(rng.choice(40, size=rng.integers(0, width + 1), replace=False))
            row = np.full(width, -1, np.int64)
            row[:len(members)] = members
            for j in range(41):
                want = j in members.tolist()
                assert kernels.listed(row, width, 0, j) == want
                assert substeps.listed(row, width, 0, j) == want


def test_collision_pairs_and_forces_match_brute_force():
    """Sweep-and-prune candidates equal the brute-force set; forces are equal and opposite."""
    rng = np.random.default_rng(5)
    body = np.ones((4, 4, 4), int)
    body[1:3, 1:3, 1:] = 0  # a cup: inner walls can touch
    robot = system.build_robot(sim.parse_scene({"body": body.tolist()}))
    batch, state = system.pack([robot])
    state.pos[:] += rng.normal(0, 0.012, state.pos.shape)
    n = len(state.pos)
    size, force, _m, _s, pairs = _work(batch, n)[:5]  # force: (3, n), rows by component
    pos, lin_mom = np.ascontiguousarray(state.pos.T), np.ascontiguousarray(state.lin_mom.T)
    size[:] = 0.05
    reach = 0.06
    count = kernels.collision_pairs(batch.surface, pos, batch.near, reach, pairs,
                                    np.zeros(n, np.int64))
    got = {tuple(sorted(p)) for p in pairs[:count]}
    want = set()
    surf = batch.surface
    for a in range(len(surf)):
        for b in range(a + 1, len(surf)):
            i, j = surf[a], surf[b]
            if np.linalg.norm(state.pos[i] - state.pos[j]) < reach and j not in batch.nbr[i]:
                want.add(tuple(sorted((i, j))))
    assert got == want and len(want) > 0
    force[:] = 0.0
    kernels.contact_forces_kernel(count, pairs, pos, lin_mom, size, batch.vconst, force)
    force = force.T
    np.testing.assert_allclose(force.sum(axis=0), 0.0, atol=1e-12)
    touching = [(i, j) for i, j in want
                if np.linalg.norm(state.pos[i] - state.pos[j]) < 0.05]
    assert touching, "the perturbed cup must have overlapping voxels"
    i, j = touching[0]
    assert (force[j] - force[i]) @ (state.pos[j] - state.pos[i]) > 0, "contacts push apart"


def _contact_case():
    """A cup of 4^3 voxels (L = 5 cm), its parts for ``contact_list_kernel``, and a call of it."""
    body = np.ones((4, 4, 4), int)
    body[1:3, 1:3, 1:] = 0
    scene = sim.parse_scene({"body": body.tolist(), "self_collisions": True})
    batch, state = system.pack([system.build_robot(scene)])
    p, voxels, _links, mine = kernels.take_robot(batch, state, 0)
    work = _work(batch, mine.pos.shape[1], collide=True)  # the body's rows by component
    assert len(work.far_first), "a small surface lists its far pairs"
    work.size[:] = 0.05
    margin = kernels.COLLIDE_MARGIN * p.L

    def collide(contacts):
        return kernels.contact_list_kernel(p, contacts, voxels.surface, voxels.near, mine.pos,
                                           work.pairs, work.partners, work.built, work.far_first,
                                           work.far, work.spos, work.outer, work.n_outer,
                                           work.outer_built)

    return p, voxels, mine, work, margin, collide


def test_candidates_are_rebuilt_only_when_the_surface_spread_over_the_margin():
    """The travel bound triggers a measurement, not a rebuild: the list is rebuilt once the
    surface voxels' displacements actually spread over the margin (one voxel moved by it:
    0.3 L = 15 mm here; half the spread is what ``travel`` holds), and then holds every pair
    within reach of the moved voxels."""
    p, voxels, mine, work, margin, collide = _contact_case()
    pos = mine.pos.T  # (n, 3): a view of the kernels' rows
    first = collide(kernels.Contacts(0, margin))  # the first step: NaN positions, so a build
    count = first.count
    assert first.travel == 0.0 and count > 0
    np.testing.assert_array_equal(work.built, pos[voxels.surface])
    inner = voxels.surface[0]
    pos[inner, 0] += 0.8 * margin  # spread 0.8 of the margin: no rebuild
    kept = collide(kernels.Contacts(count, margin))
    assert kept.travel == pytest.approx(0.4 * margin) and kept.count == count
    np.testing.assert_allclose(work.built[0], pos[inner] - [0.8 * margin, 0, 0], rtol=0,
                               atol=1e-15)  # the positions it was built from (to rounding)
    pos[inner, 0] += 0.4 * margin  # now 1.2 of the margin: rebuilt
    rebuilt = collide(kernels.Contacts(count, margin))
    assert rebuilt.travel == 0.0
    np.testing.assert_array_equal(work.built, pos[voxels.surface])
    assert kernels.surface_moved(voxels.surface, mine.pos, work.built) == 0.0


def test_a_body_moving_as_a_whole_keeps_its_candidates_and_they_hold_every_touching_pair():
    """A walk or a swim (every voxel moved alike, here by 5 margins, with a deformation that
    spreads the displacements over less than the margin on top) forces no rebuild, and the
    kept list still holds every pair that touches, against a brute-force search (the
    policy's guarantee: ``displacement_spread``)."""
    p, voxels, mine, work, margin, collide = _contact_case()
    pos = mine.pos.T  # (n, 3): a view of the kernels' rows
    work.size[:] = p.L * (1.0 + p.amp)  # fully expanded: diagonal neighbours nearly touch
    count = collide(kernels.Contacts(0, margin)).count
    listed_before = {tuple(sorted(pq)) for pq in work.pairs[:count]}
    built = work.built.copy()
    rng = np.random.default_rng(3)
    pos[:] += [5 * margin, -3 * margin, 0.5 * margin]
    pos[:] += rng.uniform(-0.2 * margin, 0.2 * margin, pos.shape)  # spread < margin
    kept = collide(kernels.Contacts(count, margin))
    assert kept.count == count and 0.0 < kept.travel < 0.5 * margin
    np.testing.assert_array_equal(work.built, built)  # not rebuilt
    assert {tuple(sorted(pq)) for pq in work.pairs[:count]} == listed_before
    near = {(int(i), int(j)) for i in range(len(voxels.near)) for j in voxels.near[i] if j >= 0}
    surface = [int(v) for v in voxels.surface]
    touching = {(i, j) for a, i in enumerate(surface) for j in surface[a + 1:]
                if (i, j) not in near and (j, i) not in near
                and np.linalg.norm(pos[i] - pos[j])
                < p.contact_reach * (work.size[i] + work.size[j])}
    assert touching, "the deformed cup must have touching unbonded pairs"
    assert touching <= {tuple(sorted((int(i), int(j)))) for i, j in work.pairs[:count]}


def test_rotation_vector_matches_scipy():
    """kernels.rotvec over the whole range of angles, either sign of the quaternion."""
    rng = np.random.default_rng(11)
    angles = np.concatenate([[0.0, 1e-9, 1e-4, 0.48, 0.4925, 0.4935, 0.5, 2.0, 3.1, np.pi],
                             rng.uniform(0, np.pi, 200)])
    for angle in angles:
        axis = rng.normal(size=3)
        r = Rotation.from_rotvec(angle * axis / np.linalg.norm(axis))
        q = ref.wxyz(r) * rng.choice([-1.0, 1.0])
        got = np.array(kernels.rotvec(*q))
        want = r.as_rotvec()
        if angle > np.pi - 1e-6:  # a half turn: +/- the same axis
            want = want if got @ want > 0 else -want
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("wave", ["sine", "square", "impulse"])
def test_actuation_with_frequency_field_matches_numpy(wave):
    """Per-voxel frequencies: every active voxel follows w(2 pi f_i t + phase_i)."""
    shape = (3, 2, 2)
    rng = np.random.default_rng(4)
    freq = rng.uniform(0.5, 8.0, shape)
    _batch, _state, _rng, _mats, scene = _robot(
        "void", seed=1, actuation={"waveform": wave, "amplitude": 0.3},
        frequency_field=freq.tolist())
    batch = _batch
    n = len(batch.flags)
    size = np.zeros(n)
    p = kernels.params(batch.fparams[0], batch.iparams[0])
    assert p.freq_field == 1
    f_v = freq[tuple(np.argwhere(scene.body > 0).T)]
    for t in rng.uniform(0, 2, 5):
        kernels.actuate_kernel(t, p, batch.flags, batch.cos_phase, batch.sin_phase,
                               batch.phase, batch.vconst, size)
        angle = 2 * np.pi * f_v * t + batch.phase
        np.testing.assert_allclose(size, expected_sizes(wave, angle, batch.flags), rtol=1e-12)


def test_mixed_collision_forces_are_equal_and_opposite():
    """Self-contact between voxels of different materials still conserves momentum."""
    rng = np.random.default_rng(6)
    body = np.ones((4, 4, 4), int)
    body[1:3, 1:3, 1:] = 0
    scene = sim.parse_scene({"body": body.tolist(),
                             "youngs_modulus_field": (10 ** rng.uniform(4, 6, (4, 4, 4))).tolist(),
                             "density_field": rng.uniform(600, 2400, (4, 4, 4)).tolist()})
    batch, state = system.pack([system.build_robot(scene)])
    state.pos[:] += rng.normal(0, 0.012, state.pos.shape)
    state.lin_mom[:] = rng.normal(0, 1e-3, state.lin_mom.shape)
    n = len(state.pos)
    size, force, _m, _s, pairs = _work(batch, n)[:5]  # force: (3, n), rows by component
    pos, lin_mom = np.ascontiguousarray(state.pos.T), np.ascontiguousarray(state.lin_mom.T)
    size[:] = 0.05
    count = kernels.collision_pairs(batch.surface, pos, batch.near, 0.06, pairs,
                                    np.zeros(n, np.int64))
    force[:] = 0.0
    kernels.contact_forces_kernel(count, pairs, pos, lin_mom, size, batch.vconst, force)
    assert np.abs(force).max() > 0
    np.testing.assert_allclose(force.sum(axis=1), 0.0, atol=1e-12 * np.abs(force).max())


@pytest.mark.parametrize("seed", range(4))
def test_far_pairs_list_the_sweeps_candidates_pair_for_pair(seed):
    """``far_candidates`` (from an outer list of the surface's pairs ``near`` never lists,
    ``outer_pairs``, taken at the candidate radius or beyond it) gives ``collision_pairs``'
    list exactly: the same pairs, ends and order, so that the contact forces are summed in the
    same order; on a lattice whose x ties the sort must break, and on bodies shaken so that
    many voxels have several candidates."""
    rng = np.random.default_rng(seed)
    body = (rng.random((5, 5, 4)) < 0.8).astype(int)
    body[2, 2, :] = 1
    robot = system.build_robot(sim.parse_scene({"body": body.tolist(), "self_collisions": True}))
    batch, state = system.pack([robot])
    n = len(state.pos)
    work = _work(batch, n, collide=True)
    assert len(work.far_first) == len(batch.surface) + 1
    for shake in (0.0, 0.005, 0.015, 0.03):
        pos = np.ascontiguousarray((state.pos + rng.normal(0, shake, state.pos.shape)).T)
        for reach in (0.06, 0.09):
            sweep = np.zeros_like(work.pairs)
            want = kernels.collision_pairs(batch.surface, pos, batch.near, reach, sweep,
                                           np.zeros(n, np.int64))
            kernels.surface_columns(batch.surface, pos, work.spos)
            for beyond in (0.0, 0.02):
                n_outer = kernels.outer_pairs(work.far_first, work.far, work.spos, reach + beyond,
                                              work.outer)
                got = kernels.far_candidates(batch.surface, work.outer, n_outer, work.spos, reach,
                                             work.pairs, np.zeros(n, np.int64))
                assert got == want
                np.testing.assert_array_equal(work.pairs[:max(got, 0)], sweep[:max(want, 0)])


def test_candidates_from_the_outer_list_stay_the_sweeps_as_the_body_moves():
    """``contact_list_kernel`` through many rebuilds, its outer list (``outer_pairs``) kept
    while the surface spreads less than OUTER_MARGIN and rebuilt after: at every rebuild the
    list is ``collision_pairs``' on the same positions, pair for pair."""
    rng = np.random.default_rng(7)
    body = np.ones((5, 4, 4), int)
    body[1:4, 1:3, 1:] = 0
    scene = sim.parse_scene({"body": body.tolist(), "self_collisions": True})
    batch, state = system.pack([system.build_robot(scene)])
    p, voxels, _links, mine = kernels.take_robot(batch, state, 0)
    n = mine.pos.shape[1]  # the body's rows by component
    work = _work(batch, n, collide=True)
    reach = kernels.candidate_radius(p.L, p.contact_reach, p.amp)
    velocity = rng.normal(0, 0.1 * p.L, mine.pos.shape)
    contacts, outer_builds, checked = kernels.Contacts(0, np.nan), 0, 0
    for _ in range(300):
        velocity += rng.normal(0, 0.02 * p.L, velocity.shape)
        mine.pos[:] += 0.02 * velocity
        before = (work.built[0, 0], work.outer_built[0, 0])
        contacts = kernels.contact_list_kernel(
            p, kernels.Contacts(contacts.count, np.inf), voxels.surface, voxels.near, mine.pos,
            work.pairs, work.partners, work.built, work.far_first, work.far, work.spos,
            work.outer, work.n_outer, work.outer_built)
        if work.built[0, 0] == before[0]:
            continue
        outer_builds += work.outer_built[0, 0] != before[1]
        sweep = np.zeros_like(work.pairs)
        want = kernels.collision_pairs(voxels.surface, mine.pos, voxels.near, reach, sweep,
                                       np.zeros(n, np.int64))
        assert contacts.count == want
        np.testing.assert_array_equal(work.pairs[:max(want, 0)], sweep[:max(want, 0)])
        checked += want > 0
    assert outer_builds >= 3 and checked >= 20, (outer_builds, checked)


def test_far_pairs_are_the_surface_pairs_near_does_not_list():
    """``far_pairs`` against the obvious double loop; none without self-collisions or over
    FAR_SURFACE voxels of surface (the sweep's case)."""
    body = np.ones((4, 3, 3), int)
    robot = system.build_robot(sim.parse_scene({"body": body.tolist(), "self_collisions": True}))
    first, far = kernels.far_pairs(robot.surface, robot.near, len(robot.pos), True)
    surf, near = robot.surface, robot.near
    for a in range(len(surf)):
        want = [b for b in range(a + 1, len(surf))
                if surf[b] not in near[surf[a]] and surf[a] not in near[surf[b]]]
        assert far[first[a]:first[a + 1]].tolist() == want
    assert len(kernels.far_pairs(surf, near, len(robot.pos), False)[0]) == 0
    big = np.arange(kernels.FAR_SURFACE + 1)
    assert len(kernels.far_pairs(big, -np.ones((len(big), 1), np.int64), len(big), True)[0]) == 0


def test_fma_rounds_once():
    """kernels.fma is a fused multiply-add: (1 + e)(1 - e) - 1 = -e^2 exactly, where the
    product rounded first gives 0; and it agrees with the plain expression elsewhere."""
    from numba import njit

    e = 2.0 ** -30
    fused = njit(lambda a, b, c: kernels.fma(a, b, c))
    assert fused(1.0 + e, 1.0 - e, -1.0) == -(e * e)
    assert (1.0 + e) * (1.0 - e) - 1.0 == 0.0
    rng = np.random.default_rng(0)
    a, b, c = rng.normal(size=(3, 100))
    got = np.array([fused(x, y, z) for x, y, z in zip(a, b, c, strict=True)])
    np.testing.assert_allclose(got, a * b + c, rtol=1e-15, atol=1e-15)


def test_a_voxel_with_more_candidates_than_the_cap_stops_the_listing():
    """The contact policy (``sim.physics``): a voxel keeps at most MAX_CONTACTS candidates;
    one more and ``collision_pairs`` says so (-1) instead of dropping a pair; at the cap
    exactly every pair is listed."""
    cap = system.MAX_CONTACTS
    for extra, want in ((0, cap * (cap + 1) // 2), (1, -1)):
        k = cap + 1 + extra  # k voxels, each within reach of the k - 1 others
        rng = np.random.default_rng(k)
        pos = rng.uniform(0.0, 0.01, (k, 3))
        surface = np.arange(k)
        near = -np.ones((k, 1), np.int64)
        pairs = np.zeros((k * cap // 2 + 1, 2), np.int64)
        partners = np.zeros(k, np.int64)
        spos = pos.T.copy()  # rows by component, as the kernels keep positions
        assert kernels.collision_pairs(surface, spos, near, 0.05, pairs, partners) == want
        first, far = kernels.far_pairs(surface, near, k, True)
        outer = np.zeros((2, len(far)), np.int32)
        n_outer = kernels.outer_pairs(first, far, spos, 0.05, outer)
        assert kernels.far_candidates(surface, outer, n_outer, spos, 0.05, pairs, partners) == want
