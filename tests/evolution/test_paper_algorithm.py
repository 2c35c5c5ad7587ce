"""The paper's algorithm and encoding choices: evosoro's Pareto selection, its control mapping
and its body rule (evolution/selection.py, evolution/genotype.py module docs)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from softevo.evolution.algorithm import Evolution, EvolutionConfig
from softevo.evolution.evaluation import EvaluationSpec
from softevo.evolution.genotype import (
    EVOSORO_MAPPINGS,
    EncodingConfig,
    Genotype,
    Phenotype,
    develop,
    evosoro_frequency,
    is_viable,
    logistic_reading,
    mutate_genotype,
    random_viable_genotype,
)
from softevo.evolution.outcome import Outcome
from softevo.evolution.runner import individual_scenes
from softevo.evolution.selection import (
    dominance_counts,
    evosoro_survivors,
    log_biased_pick,
)
from tests.evolution.conftest import hand_cppn

PAPER = EncodingConfig(workspace=(5, 5, 5), control_mapping="evosoro", body_rule="evosoro")
BIAS, X = 4, 0  # input node ids of hand_cppn


# ---- selection -------------------------------------------------------------------------------
def reference_selection(F, ages, k, rng):
    """evosoro's pareto_selection written out loop by loop (tools/selection.py): weak
    dominance with the older twin dominated, stable sorts, levels one by one, log picks."""
    n, m = F.shape
    dominated_by = [[] for _ in range(n)]
    for i in range(n):
        for j in range(n):
            if j != i and not any(F[i, c] < F[j, c] for c in range(m)) and i not in dominated_by[j]:
                dominated_by[i].append(j)
    level = [len(d) for d in dominated_by]
    order = list(range(n))
    order.sort(key=lambda i: -i)
    order.sort(key=lambda i: ages[i])
    for c in reversed(range(m)):
        order.sort(key=lambda i, c=c: F[i, c])
    order.sort(key=lambda i: level[i])
    kept, current = [], 0
    while len(kept) < k:
        this_level = [i for i in order if level[i] == current]
        if this_level and k - len(kept) >= len(this_level):
            kept += this_level
        elif this_level:
            kept.append(this_level[0])
            while len(kept) < k:
                draw = rng.random()
                size = math.log(len(this_level))
                for i in range(1, len(this_level)):
                    if math.log(i) / size <= draw < math.log(i + 1) / size and this_level[i] not in kept:
                        kept.append(this_level[i])
        current += 1
    return sorted(kept)


@pytest.mark.parametrize("seed", range(30))
def test_evosoro_survivors_match_the_loop_by_loop_reference(seed):
    data = np.random.default_rng(seed)
    n = int(data.integers(3, 25))
    F = data.integers(0, 4, size=(n, 3)).astype(float)  # small integers: many ties and twins
    ages = data.integers(0, 5, size=n)
    k = int(data.integers(1, n + 1))
    ours = evosoro_survivors(F, k, ages, np.random.default_rng(seed + 100))
    assert list(ours) == reference_selection(F, ages, k, np.random.default_rng(seed + 100))


def test_of_identical_twins_the_newest_is_not_dominated():
    F = np.array([[1.0, 1.0], [1.0, 1.0], [1.0, 1.0], [0.0, 2.0]])
    assert list(dominance_counts(F)) == [2, 1, 0, 0]
    assert list(evosoro_survivors(F, 2, np.zeros(4), np.random.default_rng(0))) == [2, 3]


def test_log_biased_pick_is_the_interval_rule():
    for size in (2, 3, 7, 30):
        for draw in np.linspace(0, 0.999999, 200):
            expected = next(
                i for i in range(1, size)
                if math.log(i) / math.log(size) <= draw < math.log(i + 1) / math.log(size)
            )
            assert log_biased_pick(size, float(draw)) == expected


def test_failed_rows_come_after_every_valid_one():
    F = np.array([[-5.0, 0.1, 3.0], [-1.0, 0.9, 30.0], [-9.0, 0.0, 1.0]])
    valid = np.array([True, True, False])
    kept = evosoro_survivors(F, 2, np.zeros(3), np.random.default_rng(0), valid)
    assert list(kept) == [0, 1]


# ---- the control mapping ---------------------------------------------------------------------
def control(frequency_weight, phase_weight):
    """A control CPPN whose outputs are constant: s = tanh(w / 2) from the bias alone."""
    return hand_cppn(("frequency", "phase"), [(BIAS, 5, frequency_weight), (BIAS, 6, phase_weight)])


def full_body(active_weight=0.0):
    """Every voxel full; active where active_weight * x >= 0 (all of them for weight 0)."""
    return hand_cppn(("present", "active"), [(BIAS, 5, 2.0), (X, 6, active_weight)])


@pytest.mark.parametrize("s, hz", [(1.0, 4.0), (0.5, 10 / 3.5), (0.25, 10 / 5.5), (-1.0, 20.0),
                                   (-0.5, -20.0), (0.1, 10 / 11.5)])
def test_evosoro_frequency_is_the_documented_formula(s, hz):
    assert evosoro_frequency(np.full((3, 3, 3), s)) == pytest.approx(hz)


def test_evosoro_frequency_averages_reciprocals_over_the_workspace():
    outputs = np.array([0.5, 1.0, -0.25, 0.8])
    expected = 4.0 * 2.5 / (np.mean(1 / outputs) + 1.5)
    assert evosoro_frequency(outputs) == pytest.approx(expected)
    assert evosoro_frequency(np.array([0.0, 0.5])) == 0.0  # no period


@pytest.mark.parametrize("weight", [3.0, 1.0, 0.2, -3.0, -1.0])
def test_develop_maps_frequency_and_phase_as_evosoro(weight):
    s_f, s_p = math.tanh(weight / 2), math.tanh(0.3 / 2)
    phenotype = develop(Genotype(full_body(), control(weight, 0.3)), PAPER)
    signed = 10.0 / (1.0 / s_f + 1.5)
    assert phenotype.frequency == pytest.approx(abs(signed))
    angle = 2 * math.pi * math.pi * (1 + s_p)  # PhaseOffset pi (1 + s), read in cycles
    if signed < 0:  # the fork's sine run backwards
        angle = math.pi - angle
    assert np.allclose(phenotype.phase, angle % (2 * math.pi))


@pytest.mark.parametrize("weight", [3.0, 1.0, 0.2, 0.05, -3.0, -1.0, -0.6])
@pytest.mark.parametrize("mapping", ["evosoro", "evosoro-bounded", "evosoro-positive",
                                     "evosoro-bounded-positive"])
def test_the_four_evosoro_mappings_bound_and_sign_as_named(mapping, weight):
    """bounded: never above the scripts' MAX_FREQUENCY of 4 Hz; positive: a negative f is
    an invalid body, never simulated; otherwise |f|. Below 4 Hz all four agree."""
    config = dataclasses.replace(PAPER, control_mapping=mapping)
    s_f = math.tanh(weight / 2)
    signed = 10.0 / (1.0 / s_f + 1.5)
    phenotype = develop(Genotype(full_body(), control(weight, 0.3)), config)
    _, bounded, positive_only = EVOSORO_MAPPINGS[mapping]
    if positive_only and signed < 0:
        assert not is_viable(phenotype, config)
        return
    expected = min(abs(signed), 4.0) if bounded else abs(signed)
    assert phenotype.frequency == pytest.approx(expected) and is_viable(phenotype, config)
    if bounded:
        assert phenotype.frequency <= 4.0
    if 0 < signed <= 4.0:
        assert phenotype.frequency == pytest.approx(signed)


def test_bounded_mapping_keeps_every_random_robot_at_or_below_4_hz(rng):
    config = dataclasses.replace(PAPER, control_mapping="evosoro-bounded")
    frequencies = [develop(random_viable_genotype(rng, config), config).frequency for _ in range(60)]
    assert max(frequencies) <= 4.0 and min(frequencies) > 0
    unbounded = [develop(random_viable_genotype(rng, PAPER), PAPER).frequency for _ in range(60)]
    assert max(unbounded) > 4.0  # the earlier mapping runs away (about 40% of random robots)


def test_the_presets_mapping_is_the_only_logistic_one():
    assert EVOSORO_MAPPINGS["evosoro-logistic"] == (True, False, False)
    assert [name for name, m in EVOSORO_MAPPINGS.items() if m.logistic] == ["evosoro-logistic"]
    assert np.allclose(logistic_reading(np.array([-1.0, 0.0, 0.5, 1.0])), [0.0, 0.5, 0.75, 1.0])
    # the logistic of the activation: (1 + tanh(x / 2)) / 2 = 1 / (1 + e^-x)
    assert logistic_reading(math.tanh(0.7 / 2)) == pytest.approx(1 / (1 + math.exp(-0.7)))


@pytest.mark.parametrize("weight", [3.0, 1.0, 0.2, 0.05, 0.0, -0.6, -1.0, -3.0])
def test_logistic_mapping_applies_the_formula_to_the_logistic_reading(weight):
    """A full body whose frequency output is tanh(w / 2) everywhere: f = 10 / (1/s' + 1.5)
    with s' = (1 + s) / 2, always in (0, 4) Hz and so never run backwards; the phase is the
    other evosoro mappings' phase, where their f is positive."""
    config = dataclasses.replace(PAPER, control_mapping="evosoro-logistic")
    s_f, s_p = math.tanh(weight / 2), math.tanh(0.3 / 2)
    reading = (1 + s_f) / 2
    phenotype = develop(Genotype(full_body(), control(weight, 0.3)), config)
    assert phenotype.frequency == pytest.approx(10.0 / (1.0 / reading + 1.5))
    assert 0 < phenotype.frequency < 4.0 and is_viable(phenotype, config)
    angle = (2 * math.pi * math.pi * (1 + s_p)) % (2 * math.pi)  # PhaseOffset pi (1 + s) in cycles
    assert np.allclose(phenotype.phase, angle)
    if s_f > 0:  # a positive bipolar f: no mapping flips the phase
        for other in ("evosoro", "evosoro-bounded", "evosoro-positive", "evosoro-bounded-positive"):
            developed = develop(Genotype(full_body(), control(weight, 0.3)),
                                dataclasses.replace(PAPER, control_mapping=other))
            assert np.array_equal(developed.phase, phenotype.phase), other


def test_logistic_mapping_spreads_random_robots_below_4_hz_without_a_pile_at_the_bound():
    """200 random viable robots of the presets' encoding (5x5x5): every f in (0, 4) Hz and no
    two alike; the clipped bipolar reading puts a share of them exactly at 4 Hz."""
    logistic = dataclasses.replace(PAPER, control_mapping="evosoro-logistic")
    rng = np.random.default_rng(2026)
    frequencies = [develop(random_viable_genotype(rng, logistic), logistic).frequency for _ in range(200)]
    assert all(0 < f < 4.0 for f in frequencies)
    assert len(set(frequencies)) == 200
    bounded = dataclasses.replace(PAPER, control_mapping="evosoro-bounded")
    rng = np.random.default_rng(2026)
    clipped = [develop(random_viable_genotype(rng, bounded), bounded).frequency for _ in range(200)]
    assert max(clipped) == 4.0 and sum(f == 4.0 for f in clipped) >= 20


def test_linear_mapping_is_unchanged_by_default():
    phenotype = develop(Genotype(full_body(), control(1.0, 0.3)), EncodingConfig(workspace=(3, 3, 3)))
    assert phenotype.frequency == pytest.approx(1.0 + (math.tanh(0.5) + 1) / 2 * 4.0)
    assert np.allclose(phenotype.phase, math.tanh(0.15) * math.pi)


def test_evosoro_mapping_refuses_per_voxel_frequencies():
    with pytest.raises(ValueError, match="frequency_per_voxel"):
        EncodingConfig(control_mapping="evosoro", frequency_per_voxel=True)


# ---- the body rule ---------------------------------------------------------------------------
def phenotype_of(full: int, active: int, shape=(5, 5, 5), frequency=2.0) -> Phenotype:
    body = np.zeros(int(np.prod(shape)), dtype=np.int8)
    body[:full] = 1
    body[:active] = 2
    return Phenotype(body.reshape(shape), np.zeros(shape), frequency)


def test_evosoro_body_rule_needs_30_percent_full_and_10_percent_active():
    # a 5x5x5 workspace: at least 37.5 -> 38 full voxels and 12.5 -> 13 active ones
    assert is_viable(phenotype_of(38, 13), PAPER)
    assert not is_viable(phenotype_of(37, 13), PAPER)
    assert not is_viable(phenotype_of(38, 12), PAPER)
    assert not is_viable(phenotype_of(125, 125, frequency=0.0), PAPER)  # no period
    assert is_viable(phenotype_of(1, 0), EncodingConfig(workspace=(5, 5, 5)))
    assert not is_viable(phenotype_of(0, 0), EncodingConfig(workspace=(5, 5, 5)))


def test_newcomers_and_children_obey_the_body_rule(rng):
    parents = [random_viable_genotype(rng, PAPER) for _ in range(10)]
    assert all(is_viable(develop(g, PAPER), PAPER) for g in parents)
    for parent in parents:
        child, _, changed = mutate_genotype(parent, rng, PAPER)
        assert is_viable(develop(child, PAPER), PAPER)
        assert changed or child is parent  # evosoro keeps the unmutated clone


def test_a_child_that_finds_no_valid_mutation_keeps_its_parent(rng):
    config = EncodingConfig(workspace=(2, 2, 2), body_rule="evosoro")
    parent = Genotype(full_body(), control(1.0, 0.3))
    impossible = EncodingConfig(workspace=(2, 2, 2), control_mapping="evosoro")
    child, ops, changed = mutate_genotype(parent, rng, config, max_tries=0)
    assert (child, ops, changed) == (parent, [], False)
    assert impossible.rejects_invalid and not EncodingConfig().rejects_invalid


# ---- the paper's algorithm -------------------------------------------------------------------
def run_generations(config, generations=3):
    algo = Evolution(config)
    for _ in range(generations + 1):
        asked = algo.ask()
        algo.tell([Outcome(float(ind.id % 7)) for ind in asked])
    return algo


def test_pareto_keeps_mu_plus_mu_without_newcomers_and_valid_bodies():
    config = EvolutionConfig(
        population_size=6, mode="pareto", evaluation=EvaluationSpec(encoding=PAPER), descriptors=False
    )
    algo = run_generations(config)
    assert len(algo.population) == 6
    assert all(ind.parent_id is not None or ind.generation_born == 0 for ind in algo.population)
    assert all(is_viable(ind.phenotype(PAPER), PAPER) for ind in algo.population)
    assert algo.next_id == 6 + 3 * 6  # six children a generation, no random newcomer
    resumed = Evolution.from_state_json(algo.state_to_json())
    assert resumed.config == config


@pytest.mark.parametrize(("world", "settle"), [("water", 0.0), ("land", 0.5)])
def test_scenes_carry_the_model_its_amplitude_and_the_fork_files_settling(rng, world, settle):
    """The fork's sample robots: InitCmTime 0.5 s on land, 0 s in water."""
    config = EvolutionConfig(population_size=2, mode="pareto", evaluation=EvaluationSpec(
        world, encoding=PAPER, model="voxcad-land-water"))
    algo = Evolution(config)
    (scene,) = individual_scenes(algo, algo.ask()[0])
    assert scene["model"] == "voxcad-land-water"
    assert scene["actuation"]["amplitude"] == pytest.approx(0.14)
    assert scene["settle_seconds"] == pytest.approx(settle)
    default = Evolution(EvolutionConfig(population_size=2, evaluation=EvaluationSpec("water")))
    (plain,) = individual_scenes(default, default.ask()[0])
    assert "model" not in plain and plain["actuation"]["amplitude"] == pytest.approx(0.39)
    assert plain["settle_seconds"] == 0.0
    with pytest.raises(ValueError, match="model"):
        EvolutionConfig(evaluation=EvaluationSpec(model="voxelyze-3"))
