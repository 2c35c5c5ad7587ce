import numpy as np
import pytest

from softevo.evolution.genotype import (
    EncodingConfig,
    Genotype,
    Phenotype,
    develop,
    largest_component,
    random_viable_genotype,
)

from .conftest import hand_cppn

X, Y, Z, D, BIAS = range(5)
BODY_PRESENT, BODY_ACTIVE = 5, 6
CONTROL_FREQUENCY, CONTROL_PHASE = 5, 6


def genotype(body_links, control_links, body_outputs=("present", "active")):
    return Genotype(
        hand_cppn(body_outputs, body_links), hand_cppn(("frequency", "phase"), control_links)
    )


def test_expression_pattern():
    # present where x >= 0 (sigmoid of 5x), active where y >= 0, phase = tanh(z/2) * pi,
    # frequency output = tanh(bias/2) everywhere
    g = genotype(
        [(X, BODY_PRESENT, 5.0), (Y, BODY_ACTIVE, 5.0)],
        [(BIAS, CONTROL_FREQUENCY, 1.0), (Z, CONTROL_PHASE, 1.0)],
    )
    config = EncodingConfig(workspace=(5, 4, 3), frequency_range=(1.0, 5.0))
    p = develop(g, config)
    assert p.body.dtype == np.int8 and p.body.shape == (5, 4, 3)
    assert np.all(p.body[:2] == 0)  # x < 0: empty (x = -1, -0.5)
    assert np.all(p.body[2:, :2] == 1) and np.all(p.body[2:, 2:] == 2)  # y < 0 passive
    z = np.array([-1.0, 0.0, 1.0])
    assert np.allclose(p.phase[2:], np.tanh(z / 2) * np.pi)
    assert np.all(p.phase[:2] == 0)
    m = np.tanh(0.5)
    assert p.frequency == pytest.approx(1.0 + (m + 1) / 2 * 4.0)
    assert p.removed_voxels == 0
    assert p.voxel_count == 3 * 4 * 3
    assert p.active_share == pytest.approx(0.5)


def test_only_the_largest_component_is_kept_and_the_removal_recorded():
    # present where |x| is large: two slabs x = -1 and x = +1 plus... make them unequal with z
    # present = sigmoid(5 * (x^2-ish)) is hard to hand-build; test the helper directly.
    full = np.zeros((5, 5, 5), dtype=bool)
    full[0, 0, 0:3] = True  # 3 voxels
    full[4, 4, :] = True  # 5 voxels
    full[2, 2, 2] = full[2, 3, 3] = True  # diagonal contact only: not face-connected
    kept = largest_component(full)
    assert kept.sum() == 5 and kept[4, 4].all()
    assert largest_component(np.zeros((2, 2, 2), bool)).sum() == 0


def test_develop_records_removed_voxels():
    # present where gaussian-ish: |x| large -> sigmoid(5*(|x| - 0.6)) via a hidden abs node
    body = hand_cppn(
        ("present", "active"),
        [(X, 10, 1.0), (10, BODY_PRESENT, 5.0), (BIAS, BODY_PRESENT, -3.0)],
        hidden=[(10, "abs")],
    )
    g = Genotype(body, hand_cppn(("frequency", "phase"), []))
    p = develop(g, EncodingConfig(workspace=(5, 3, 3)))
    # slabs x = -1 and x = 1 (|x| = 1 >= 0.6) are equal; the first in x-major order is kept
    assert p.voxel_count == 9 and p.removed_voxels == 9
    assert np.all(p.body[0] > 0) and np.all(p.body[4] == 0)
    assert np.all(p.phase[4] == 0)


def test_phenotype_hash_is_stable_and_sensitive():
    rng = np.random.default_rng(2)
    config = EncodingConfig(workspace=(4, 4, 4))
    g = random_viable_genotype(rng, config)
    a, b = develop(g, config), develop(Genotype.from_json(g.to_json()), config)
    assert a.phenotype_hash() == b.phenotype_hash()
    assert len(a.phenotype_hash()) == 40
    moved = Phenotype(a.body, a.phase, a.frequency + 0.01)
    assert moved.phenotype_hash() != a.phenotype_hash()
    body = a.body.copy()
    body[np.nonzero(body)[0][0], np.nonzero(body)[1][0], np.nonzero(body)[2][0]] = 0
    assert Phenotype(body, a.phase, a.frequency).phenotype_hash() != a.phenotype_hash()


def test_to_scene_follows_the_schema():
    g = genotype([(X, BODY_PRESENT, 5.0), (BIAS, BODY_ACTIVE, 1.0)], [(Z, CONTROL_PHASE, 1.0)])
    p = develop(g, EncodingConfig(workspace=(3, 3, 3)))
    land = p.to_scene("land", 1e6, cycles=7)
    assert land["settle_seconds"] == 0.5 and land["duration"] == {"cycles": 7}
    assert land["material"] == {"youngs_modulus": 1e6, "density": 1200.0, "poisson_ratio": 0.4}
    assert land["voxel_size"] == 0.05 and land["actuation"]["amplitude"] == 0.39
    assert land["environment"] == {"kind": "land"}
    assert np.array_equal(np.array(land["body"]), p.body)
    water = p.to_scene("water", 1e5)
    assert water["settle_seconds"] == 0.0 and water["duration"] == {"cycles": 50}
    import json

    json.dumps(land)  # plain JSON types only
    from softevo import sim
    scene = sim.parse_scene(land)
    assert np.array_equal(scene.body, p.body)


def test_stiffness_and_frequency_field_options():
    g = genotype(
        [(X, BODY_PRESENT, 0.0), (BIAS, BODY_PRESENT, 1.0), (X, 7, 100.0)],
        [(X, CONTROL_FREQUENCY, 100.0)],
        body_outputs=("present", "active", "stiffness"),
    )
    config = EncodingConfig(
        workspace=(3, 1, 1),
        evolve_stiffness=True,
        frequency_per_voxel=True,
        stiffness_range=(1e3, 1e7),
        frequency_range=(1.0, 5.0),
    )
    p = develop(g, config)
    assert np.allclose(p.stiffness[:, 0, 0], [1e3, 1e5, 1e7], rtol=1e-6)
    assert np.allclose(p.frequency_field[:, 0, 0], [1.0, 3.0, 5.0], atol=1e-6)
    assert p.frequency == pytest.approx(3.0)  # mean output 0 -> middle of the range
    assert develop(g, EncodingConfig(workspace=(3, 1, 1))).stiffness is None
    # both fields enter the scene, which the simulator accepts; without the options, neither
    scene = p.to_scene("water", 1e5, 4)
    assert np.array_equal(scene["youngs_modulus_field"], p.stiffness)
    assert np.array_equal(scene["frequency_field"], p.frequency_field)
    from softevo.sim import parse_scene

    parsed = parse_scene(scene)
    active = p.body == 2
    if active.any():
        assert parsed.duration_seconds == pytest.approx(4 / p.frequency_field[active].mean())
    plain = develop(g, EncodingConfig(workspace=(3, 1, 1))).to_scene("water", 1e5)
    assert "youngs_modulus_field" not in plain and "frequency_field" not in plain
