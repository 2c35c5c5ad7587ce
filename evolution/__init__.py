"""The evolution core: CPPN encoding, AFPO / Pareto selection (ask/tell), shape descriptors.

A pure library: genome -> phenotype -> scene, results -> objectives -> selection. It imports
neither worker/ nor service/; evaluation is a function passed in (see ``runner.run``).

Main entry points:
- ``CPPN``, ``express``: genome data and vectorised expression (``evolution.cppn``);
- ``Genotype``, ``Phenotype``, ``EncodingConfig``, ``develop`` (``evolution.genotype``);
- ``evaluation_scenes``: the one path from a phenotype to the scenes of its evaluation in a
  pure or compound world (``evolution.evaluation``; the workers' ``worker.tasks.scenes_of``
  goes through it);
- ``Outcome``: what an evaluation returns, a compound world's parts combined
  (``evolution.outcome``);
- ``Evolution``, ``EvolutionConfig``: the ask/tell algorithm, and ``Algorithm``, the record
  of operators (``evolution.operators``) each registered algorithm is (``evolution.algorithm``);
- ``Individual`` (``evolution.individual``);
- ``describe`` (``evolution.descriptors``, numba kernels compiled on first use; imported lazily);
- ``run``: a local run loop, and ``ask_generation``, the ask and environment switch it
  shares with the service's coordinator (``evolution.runner``);
- ``Schedule``: environments by generation, and the switch (``evolution.schedule``).
"""

from softevo.evolution.algorithm import Algorithm, Evolution, EvolutionConfig
from softevo.evolution.cppn import CPPN, express
from softevo.evolution.evaluation import evaluation_scenes
from softevo.evolution.genotype import EncodingConfig, Genotype, Phenotype, develop
from softevo.evolution.individual import Individual
from softevo.evolution.outcome import Outcome
from softevo.evolution.runner import ask_generation, run
from softevo.evolution.schedule import Schedule
from softevo.evolution.selection import Objective, crowding_distance, non_dominated_sort

__all__ = [
    "Algorithm",
    "CPPN",
    "EncodingConfig",
    "Evolution",
    "EvolutionConfig",
    "Genotype",
    "Individual",
    "Objective",
    "Outcome",
    "Phenotype",
    "Schedule",
    "ask_generation",
    "crowding_distance",
    "describe",
    "develop",
    "evaluation_scenes",
    "express",
    "non_dominated_sort",
    "run",
]


def __getattr__(name: str):
    if name == "describe":
        from softevo.evolution.descriptors import describe

        return describe
    raise AttributeError(f"module 'evolution' has no attribute {name!r}")

if __name__ != "softevo.evolution":  # installed as softevo.evolution (pyproject.toml): one name, one module
    raise ImportError(f"import softevo.evolution, not {__name__}")
