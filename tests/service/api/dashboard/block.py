"""A 7x7x7 block robot for the replay frame-rate measurement: every voxel present, the half
with x >= 0 active, phases varying along x and z."""

from __future__ import annotations

import numpy as np

from softevo.evolution.cppn import INPUT_NAMES, minimal_cppn
from softevo.evolution.genotype import EncodingConfig, Genotype, develop

WORKSPACE = (7, 7, 7)


def _weights(outputs: dict[str, dict[str, float]]) -> np.ndarray:
    """(n_inputs, n_outputs) weights from {output: {input name: weight}}."""
    weights = np.zeros((len(INPUT_NAMES), len(outputs)))
    for column, links in enumerate(outputs.values()):
        for name, weight in links.items():
            weights[INPUT_NAMES.index(name), column] = weight
    return weights


def block_genome() -> dict:
    """Genotype.to_dict() of the block robot."""
    body = minimal_cppn(("present", "active"), _weights({"present": {"bias": 3.0}, "active": {"x": 4.0}}))
    control = minimal_cppn(("frequency", "phase"), _weights({"frequency": {}, "phase": {"x": 2.0, "z": 1.0}}))
    genotype = Genotype(body, control)
    phenotype = develop(genotype, EncodingConfig(workspace=WORKSPACE))
    assert phenotype.voxel_count == 343, phenotype.voxel_count
    return genotype.to_dict()
