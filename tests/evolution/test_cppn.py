import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from softevo.evolution.cppn import ACTIVATIONS, CPPN, GenomeError, Link, express, workspace_inputs
from softevo.evolution.genotype import EncodingConfig, random_cppn
from softevo.evolution.mutation import mutate_cppn

from .conftest import hand_cppn


def reference_output(cppn: CPPN, inputs: dict[str, float]) -> dict[str, float]:
    """Slow, obvious evaluation of one voxel by recursion over incoming links."""
    by_id = cppn.node_by_id

    def value(node_id: int) -> float:
        node = by_id[node_id]
        if node.role == "input":
            return inputs[node.name]
        total = sum(lk.weight * value(lk.source) for lk in cppn.links if lk.target == node_id)
        activation = "sigmoid" if node.role == "output" else node.activation
        return float(ACTIVATIONS[activation](np.array(total)))

    return {by_id[o].name: value(o) for o in cppn.output_ids}


def evolved_cppn(seed: int, n_mutations: int) -> CPPN:
    rng = np.random.default_rng(seed)
    cppn = random_cppn(rng, ("present", "active"), EncodingConfig())
    for _ in range(n_mutations):
        cppn, _ = mutate_cppn(cppn, rng)
    return cppn


def test_inputs_span_the_documented_ranges():
    inputs = workspace_inputs((3, 5, 1))
    x, y, z, d, bias = inputs
    assert x.min() == -1 and x.max() == 1 and y.min() == -1 and y.max() == 1
    assert np.all(z == 0)  # a dimension of size 1 sits at the centre
    assert np.all(bias == 1)
    cube = workspace_inputs((3, 3, 3))
    assert cube[3].min() == 0.0  # centre voxel
    assert cube[3].max() == pytest.approx(1.0)  # corners
    # x-major (C) order: voxel (i, j, k) is column i*ny*nz + j*nz + k
    assert inputs[0].reshape(3, 5, 1)[2, 0, 0] == 1.0


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(0, 40))
def test_express_matches_a_per_voxel_reference(seed, n):
    cppn = evolved_cppn(seed, n)
    shape = (3, 2, 4)
    fast = express(cppn, shape)
    inputs = workspace_inputs(shape)
    for voxel in range(0, inputs.shape[1], 5):
        point = dict(zip(("x", "y", "z", "d", "bias"), inputs[:, voxel], strict=True))
        slow = reference_output(cppn, point)
        for name, value in slow.items():
            assert fast[name].ravel()[voxel] == pytest.approx(value, rel=1e-9, abs=1e-12)


def test_outputs_are_named_shaped_and_squashed():
    cppn = hand_cppn(("present", "active"), [(0, 5, 100.0), (4, 6, -100.0)])
    out = express(cppn, (4, 3, 2))
    assert set(out) == {"present", "active"}
    assert all(a.shape == (4, 3, 2) for a in out.values())
    assert np.all(np.abs(out["present"]) <= 1) and np.all(out["active"] < -0.99)
    # present follows the sign of x
    assert np.all(out["present"][:2] < 0) and np.all(out["present"][2:] > 0)


def test_output_without_links_is_zero():
    out = express(hand_cppn(("present",), []), (2, 2, 2))
    assert np.all(out["present"] == 0.0)


def test_activations_have_their_documented_form():
    s = np.array([-2.0, -0.5, 0.0, 0.5, 2.0])
    assert np.allclose(ACTIVATIONS["sigmoid"](s), 2 / (1 + np.exp(-s)) - 1)
    assert np.allclose(ACTIVATIONS["gaussian"](s), 2 * np.exp(-(s**2)) - 1)
    assert np.allclose(ACTIVATIONS["neg_sqrt_abs"](s), -np.sqrt(np.abs(s)))
    assert np.allclose(ACTIVATIONS["neg_square"](s), -(s**2))
    assert len(ACTIVATIONS) == 10


@settings(max_examples=50, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(0, 60))
def test_json_round_trip_is_exact(seed, n):
    cppn = evolved_cppn(seed, n)
    again = CPPN.from_json(cppn.to_json())
    assert again == cppn
    assert again.to_json() == cppn.to_json()
    for name, array in express(again, (3, 3, 3)).items():
        assert np.array_equal(array, express(cppn, (3, 3, 3))[name])


def test_invalid_genomes_are_rejected():
    good = hand_cppn(
        ("present",), [(0, 10, 1.0), (10, 11, 1.0), (11, 5, 1.0)], hidden=[(10, "sin"), (11, "abs")]
    )
    good.validate()
    cyclic = CPPN(good.nodes, good.links + (Link(11, 10, 1.0),))
    with pytest.raises(GenomeError, match="cycle"):
        cyclic.validate()
    dangling = CPPN(good.nodes, good.links + (Link(99, 5, 1.0),))
    with pytest.raises(GenomeError, match="dangling"):
        dangling.validate()
    into_input = CPPN(good.nodes, good.links + (Link(10, 0, 1.0),))
    with pytest.raises(GenomeError, match="input"):
        into_input.validate()
    data = json.loads(good.to_json())
    data["nodes"][-1][2] = "tanhh"
    with pytest.raises(GenomeError, match="activation"):
        CPPN.from_json(json.dumps(data))
