import numpy as np

from softevo.evolution.cppn import CPPN, express
from softevo.evolution.genotype import (
    EncodingConfig,
    develop,
    mutate_developed,
    mutate_genotype,
    random_cppn,
    random_viable,
    random_viable_genotype,
)
from softevo.evolution.mutation import OPERATORS, add_link, add_node, candidate_links, mutate_cppn


def test_ten_thousand_mutations_never_make_an_invalid_genome():
    rng = np.random.default_rng(7)
    config = EncodingConfig()
    used = set()
    for _lineage in range(20):
        cppn = random_cppn(rng, ("present", "active"), config)
        for _ in range(500):
            cppn, op = mutate_cppn(cppn, rng)
            used.add(op)
            cppn.validate()  # acyclic, no dangling or duplicate links, roles respected
            assert CPPN.from_json(cppn.to_json()) == cppn
        assert set(cppn.output_names) == {"present", "active"}
    assert used == set(OPERATORS)


def test_add_node_splits_a_link_and_keeps_the_function_for_identity():
    rng = np.random.default_rng(0)
    cppn = random_cppn(rng, ("present",), EncodingConfig(initial_hidden_nodes=0, initial_links=0))
    child = add_node(cppn, rng)
    assert len(child.nodes) == len(cppn.nodes) + 1
    assert len(child.links) == len(cppn.links) + 1
    hidden = child.hidden_ids[0]
    into = [lk for lk in child.links if lk.target == hidden]
    assert len(into) == 1 and into[0].weight == 1.0


def test_add_link_never_closes_a_cycle():
    rng = np.random.default_rng(3)
    cppn = random_cppn(rng, ("present",), EncodingConfig(initial_hidden_nodes=6))
    for _ in range(200):
        child = add_link(cppn, rng)
        if child is None:
            assert candidate_links(cppn) == []
            break
        child.validate()
        cppn = child


def test_child_differs_from_parent_in_phenotype():
    rng = np.random.default_rng(11)
    config = EncodingConfig(workspace=(5, 5, 5))
    for _ in range(30):
        parent = random_viable_genotype(rng, config)
        child, ops, changed = mutate_genotype(parent, rng, config)
        assert changed and ops
        assert develop(child, config).phenotype_hash() != develop(parent, config).phenotype_hash()


def test_mutation_depends_only_on_the_generator():
    config = EncodingConfig()
    a = random_viable_genotype(np.random.default_rng(5), config)
    b = random_viable_genotype(np.random.default_rng(5), config)
    assert a == b
    child_a = mutate_genotype(a, np.random.default_rng(9), config)
    child_b = mutate_genotype(b, np.random.default_rng(9), config)
    assert child_a == child_b
    out = express(child_a[0].body, (3, 3, 3))
    assert set(out) == {"present", "active"}


def _same_phenotype(a, b) -> bool:
    return a.phenotype_hash() == b.phenotype_hash() and np.array_equal(a.phase, b.phase)


def test_breeding_with_the_phenotypes_in_hand_draws_and_returns_what_developing_again_does():
    """``mutate_developed`` (the parent's phenotype given, the child's returned) and
    ``random_viable`` make the same children from the same generator as ``mutate_genotype``
    and ``random_viable_genotype``, and their phenotypes are those ``develop`` gives."""
    for config in (EncodingConfig(workspace=(5, 5, 5)),
                   EncodingConfig(workspace=(6, 6, 6), control_mapping="evosoro", body_rule="evosoro")):
        rng_a, rng_b = np.random.default_rng(21), np.random.default_rng(21)
        for _ in range(12):
            parent = random_viable_genotype(rng_a, config)
            same_parent, parent_phenotype = random_viable(rng_b, config)
            assert same_parent == parent and _same_phenotype(parent_phenotype, develop(parent, config))
            child, ops, changed = mutate_genotype(parent, rng_a, config)
            assert mutate_developed(parent, parent_phenotype, rng_b, config)[:3] == (child, ops, changed)
            rng_c = np.random.default_rng(int(rng_a.integers(1 << 30)))
            rng_b.integers(1 << 30)
            given_up = mutate_developed(parent, parent_phenotype, rng_c, config, max_tries=0)
            assert given_up == (parent, [], False, parent_phenotype)
        returned = mutate_developed(parent, parent_phenotype, np.random.default_rng(3), config)
        assert _same_phenotype(returned[3], develop(returned[0], config))
