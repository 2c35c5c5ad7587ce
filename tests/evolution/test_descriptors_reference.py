"""The descriptors (counted on the lattice, evolution/descriptors.py) against the slow, obvious
computation they replace: the surface mesh built as triangles and measured by trimesh (its
volume, its convex hull, its vertex defects), and the symmetry shares sliced with NumPy.

Tolerances: 1e-12 (absolute) on the symmetry index, the branching index and the entropy,
1e-9 rad on each vertex's curvature (trimesh sums floating-point face angles; the lattice
count gives exact multiples of pi/2 up to one rounding).
"""

import numpy as np
import pytest

from softevo.evolution import descriptors
from tests.evolution._descriptor_reference import (
    reference_branching,
    reference_curvature,
    reference_describe,
    reference_entropy,
    reference_symmetry_axes,
    surface_mesh,
)


# ---- bodies -------------------------------------------------------------------------------------
def random_bodies(count: int, seed: int = 0):
    """Random bodies of many shapes and fill rates (several components, holes, thin parts)."""
    rng = np.random.default_rng(seed)
    for _ in range(count):
        shape = tuple(rng.integers(1, 8, size=3))
        body = rng.choice([0, 1, 2], size=shape, p=[1 - (q := rng.uniform(0.1, 0.95)), q / 2, q / 2])
        if not body.any():
            body.flat[0] = 1
        yield body.astype(np.int8)


def edge_cases():
    hollow = np.ones((5, 5, 5), np.int8)
    hollow[2, 2, 2] = 0  # a closed cavity
    tunnel = np.ones((4, 4, 3), np.int8)
    tunnel[1:3, 1:3, :] = 0  # a hole through
    diagonal = np.zeros((3, 3, 3), np.int8)
    diagonal[0, 0, 0] = diagonal[1, 1, 1] = diagonal[2, 2, 2] = 1  # three components at corners
    edge_touch = np.zeros((2, 2, 1), np.int8)
    edge_touch[0, 0, 0] = edge_touch[1, 1, 0] = 2  # two voxels sharing an edge
    staircase = np.zeros((4, 4, 4), np.int8)
    for k in range(4):
        staircase[k, : k + 1, : 4 - k] = 1
    return {
        "one voxel": np.ones((1, 1, 1), np.int8),
        "line x": np.ones((7, 1, 1), np.int8),
        "line z in a workspace": np.pad(np.ones((1, 1, 5), np.int8), 1),
        "plate": np.ones((4, 3, 1), np.int8),
        "full cube": np.full((7, 7, 7), 2, np.int8),
        "cavity": hollow,
        "tunnel": tunnel,
        "corner-touching": diagonal,
        "edge-touching": edge_touch,
        "staircase": staircase,
    }


ALL_BODIES = [*edge_cases().values(), *random_bodies(150)]
IDS = [*edge_cases(), *(f"random {k}" for k in range(150))]


@pytest.mark.parametrize("body", ALL_BODIES, ids=IDS)
def test_symmetry_agrees_with_numpy_slices(body):
    np.testing.assert_allclose(descriptors.symmetry_axes(body), reference_symmetry_axes(body),
                               rtol=0, atol=1e-12)


@pytest.mark.parametrize("body", ALL_BODIES, ids=IDS)
def test_branching_agrees_with_trimesh(body):
    assert descriptors.branching_index(body) == pytest.approx(reference_branching(body), abs=1e-12)


@pytest.mark.parametrize("body", ALL_BODIES, ids=IDS)
def test_curvature_and_entropy_agree_with_trimesh(body):
    np.testing.assert_allclose(descriptors.surface_curvature(body), reference_curvature(body),
                               rtol=0, atol=1e-9)
    assert descriptors.shape_entropy(body) == pytest.approx(reference_entropy(body), abs=1e-12)


@pytest.mark.parametrize("radius", [0.5, 1.0, 1.5, 2.0])
def test_curvature_over_a_ball_agrees_with_trimesh(radius):
    for body in [*edge_cases().values(), *random_bodies(15, seed=1)]:
        np.testing.assert_allclose(descriptors.surface_curvature(body, radius),
                                   reference_curvature(body, radius), rtol=0, atol=1e-9)
        assert descriptors.shape_entropy(body, radius) == pytest.approx(
            reference_entropy(body, radius), abs=1e-12)


def test_describe_agrees_with_the_reference_on_developed_robots():
    from softevo.evolution.genotype import EncodingConfig, random_viable

    config = EncodingConfig(control_mapping="evosoro-bounded", body_rule="evosoro")
    rng = np.random.default_rng(3)
    for _ in range(20):
        _, phenotype = random_viable(rng, config)
        fast = descriptors.describe_phenotype(phenotype)
        slow = reference_describe(phenotype.body, phenotype.frequency)
        assert fast.keys() == slow.keys()
        for key, value in slow.items():
            assert fast[key] == pytest.approx(value, abs=1e-12), key
            assert type(fast[key]) is type(value), key


def test_the_reference_mesh_is_closed_and_holds_the_voxels():
    for body in edge_cases().values():
        mesh = surface_mesh(body)
        assert mesh.volume == pytest.approx(np.count_nonzero(body))


def test_hull_volume_agrees_with_qhull_on_lattice_points():
    from scipy.spatial import ConvexHull

    rng = np.random.default_rng(2)
    assert descriptors.hull_volume(np.argwhere(np.ones((2, 2, 2)))) == 1.0
    assert descriptors.hull_volume(np.argwhere(np.ones((3, 3, 1)))) == 0.0  # coplanar
    for _ in range(200):
        points = rng.integers(0, rng.integers(2, 9), size=(rng.integers(4, 60), 3))
        if np.linalg.matrix_rank(points[1:] - points[0]) < 3:
            continue
        assert descriptors.hull_volume(points) == pytest.approx(ConvexHull(points).volume, abs=1e-9)
