"""Time ``express`` for a 7^3 workspace with two 20-node CPPNs (target: under 1 ms for both).

Run: ``python bench/express_speed.py``. Prints the median time of expressing the body and
the control CPPN of one genotype, and of the full ``develop`` (expression + thresholds +
largest component) for comparison.
"""

from __future__ import annotations

import timeit

import numpy as np

from softevo.evolution.cppn import CPPN, express, minimal_cppn
from softevo.evolution.genotype import EncodingConfig, Genotype, develop
from softevo.evolution.mutation import add_link, add_node

WORKSPACE = (7, 7, 7)


def cppn_with_nodes(rng: np.random.Generator, outputs: tuple[str, ...], n_nodes: int) -> CPPN:
    """A CPPN of exactly ``n_nodes`` nodes (5 inputs, the outputs, hidden) and 2 links per
    hidden node on top of the split links."""
    cppn = minimal_cppn(outputs, rng.uniform(-1, 1, (5, len(outputs))))
    while len(cppn.nodes) < n_nodes:
        cppn = add_node(cppn, rng)
    for _ in range(2 * len(cppn.hidden_ids)):
        cppn = add_link(cppn, rng) or cppn
    return cppn


def main() -> None:
    rng = np.random.default_rng(0)
    genotype = Genotype(
        cppn_with_nodes(rng, ("present", "active"), 20),
        cppn_with_nodes(rng, ("frequency", "phase"), 20),
    )
    config = EncodingConfig(workspace=WORKSPACE)

    def both() -> None:
        express(genotype.body, WORKSPACE)
        express(genotype.control, WORKSPACE)

    both()  # warm the input grid cache and the evaluation plans
    runs = 2000
    express_s = np.median(timeit.repeat(both, number=runs, repeat=5)) / runs
    develop_s = np.median(timeit.repeat(lambda: develop(genotype, config), number=200, repeat=5))
    links = len(genotype.body.links) + len(genotype.control.links)
    print(f"express, 7^3 workspace, two 20-node CPPNs ({links} links): {express_s * 1e3:.3f} ms")
    print(f"develop (expression + phenotype): {develop_s / 200 * 1e3:.3f} ms")


if __name__ == "__main__":
    main()
