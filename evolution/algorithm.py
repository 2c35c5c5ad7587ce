"""The ask/tell algorithm (``Evolution``) and the algorithms it runs: each a registered
``Algorithm`` composed of operators (``evolution.operators``), as pymoo composes its own:
the objectives it adds to the run's, its survival and its variations. ``pareto`` (the
paper's plain Pareto optimisation), ``afpo`` (Age-Fitness Pareto Optimisation) and
``map-elites`` (MAP-Elites over the run's grid of traits, ``EvolutionConfig.grid``) are three
registrations; a new algorithm is one more (``register``; ``names()`` lists them). A run's
``EvolutionConfig.mode`` names its algorithm.

``map-elites`` (docs/algorithm.md): its survival keeps the elites of a pyribs ``GridArchive``
fed survivors and offspring in id order (``operators.archive_survival``), so its population
is the archive, however many cells are filled; its variation makes ``population_size``
children of parents drawn uniformly from the elites (``operators.uniform_mutants``). Each
candidate's measures are its traits as storage records them (``Individual.trait_values``),
so the archive after each generation is ``archive.elites`` replayed over the stored
evaluations (``archive.current``).

A generation:
1. every survivor's age grows by one;
2. the algorithm's variations make the new individuals, in order: for both built-in ones
   every survivor makes one mutated child (which inherits its parent's age and differs from
   it in phenotype, see ``mutate_genotype``); in ``afpo`` one random newcomer of age 0 joins
   too; a generation without any new individual gets one newcomer;
3. the new individuals are handed out by :meth:`Evolution.ask` and their results come back
   through :meth:`Evolution.tell`;
4. survivors and offspring together (parents survive: a (mu + mu) scheme) are cut back to
   ``population_size`` by the algorithm's survival:
   - ``pareto``, the paper's algorithm (its section 2.4: three objectives, mutation
     only; evosoro's ``ParetoOptimization``, tools/algorithms.py:97-148, 156-158): over the
     three objectives alone, by evosoro's ``pareto_selection``
     (``selection.evosoro_survivors``: levels by dominance count, the newer of identical
     twins preferred, a log-biased random pick within the level that does not fit);
   - ``afpo`` (Schmidt & Lipson 2011, the remedy the paper names for premature
     convergence): over the objectives plus age (minimised), by successive non-dominated
     fronts; the front that does not fit whole is cut by crowding distance, then by lower id
     (the older individual) (``selection.select_survivors``).
evosoro's ``run`` adds ``num_random_individuals`` newcomers (default 1) whatever the
objectives; the paper describes none and names age-based diversity as future work, so
``pareto`` adds none.

Failed evaluations (a crash, an unstable simulation, an empty body, a body the encoding's
body rule rejects) get distance 0 and rank behind every successful individual.
Offspring whose phenotype hash equals a living individual's evaluated in the same
environment inherit that evaluation instead of being simulated again. Survivors are never
simulated again in the world they were evaluated in: ``ask`` hands out only this
generation's new individuals (all of them, survivors included, after ``reevaluate_all``
moved the population to a new world) and refuses to hand out a survivor (RuntimeError).
``not_simulated`` counts this generation's individuals evaluated without a simulation
(``reused`` from a living twin, ``empty`` bodies, rejected ones included, and ``passive``
bodies).

A passive body (no active voxel) is not simulated: it travels ``PASSIVE_DISTANCE`` (0), a
valid evaluation. It cannot move itself; what a simulation measures for it is its fall: a
tall body that topples after settling travels about 1.6 voxel lengths, and with the least
active share it would sit on the Pareto front of distance against active share. Robots
with active voxels that topple still count their fall (the settling time is the world's,
``sim.worlds.World.settle_seconds``): detecting that in the simulator is left open.

The whole state (including the random generator) is JSON: ``state_to_json`` /
``from_state_json``; a resumed run continues exactly as the uninterrupted one.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from softevo.evolution.archive import Grid
from softevo.evolution.evaluation import EvaluationSpec
from softevo.evolution.genotype import (
    EncodingConfig,
    is_viable,
    mutate_developed,
    random_viable,
)
from softevo.evolution.individual import Individual
from softevo.evolution.operators import (
    Candidates,
    Survival,
    Variation,
    archive_survival,
    evosoro_survival,
    mutate_each,
    nsga2_survival,
    random_newcomers,
    uniform_mutants,
)
from softevo.evolution.outcome import Outcome
from softevo.evolution.selection import (
    AGE_OBJECTIVE,
    PAPER_OBJECTIVES,
    Objective,
    objective_matrix,
    objective_named,
    objective_values,
)
from softevo.sim import models
from softevo.sim.registry import Registry


@dataclass(frozen=True)
class Algorithm:
    """An algorithm as a record of operators (``evolution.operators``): ``name`` (a run's
    ``EvolutionConfig.mode``), ``survival`` (cuts survivors and offspring back to the
    population size), ``variations`` (each makes part of a generation's new individuals
    from the survivors, their offspring joined in order), ``objectives`` it adds to the
    run's for selection (AFPO's ``age``, the one objective given at selection rather than
    computed; one with a value function is computed for each evaluation as the run's are),
    ``archive`` (its survival keeps a MAP-Elites archive over the run's grid,
    ``EvolutionConfig.grid``: its candidates carry their measures) and a one-line
    ``description``."""

    name: str
    survival: Survival
    variations: tuple[Variation, ...] = (mutate_each,)
    objectives: tuple[Objective, ...] = ()
    description: str = ""
    archive: bool = False


AFPO = Algorithm(
    "afpo", nsga2_survival, (mutate_each, random_newcomers(1)), (AGE_OBJECTIVE,),
    "Age-Fitness Pareto Optimisation: the objectives plus age, one random newcomer a generation")
PARETO = Algorithm(
    "pareto", evosoro_survival, (mutate_each,), (),
    "the paper's: evosoro's Pareto selection over the objectives, mutation only")

MAP_ELITES = Algorithm(
    "map-elites", archive_survival, (uniform_mutants,), (),
    "MAP-Elites: the farthest robot of each cell of a grid of traits, parents drawn uniformly from them",
    archive=True)

ALGORITHMS: Registry[Algorithm] = Registry("algorithm", (AFPO, PARETO, MAP_ELITES))
"""The algorithms a run may name (``EvolutionConfig.mode``, a treatment's ``algorithm``)."""
register, unregister, get = ALGORITHMS.register, ALGORITHMS.unregister, ALGORITHMS.get


def names() -> tuple[str, ...]:
    """The registered algorithms' names, the built-in ones first (the choices of ``softevo
    run --algorithm`` and of REST)."""
    return ALGORITHMS.names()


PAPER_POPULATION = 30  # the paper's population size (docs/spec.md section 5)

PASSIVE_DISTANCE = 0.0  # a body without an active voxel: it cannot move itself (issue 49.7)


@dataclass(frozen=True)
class EvolutionConfig:
    """Everything that defines a run's algorithm and its evaluations.

    evaluation: the ``EvaluationSpec`` of the run's evaluations (its ``environment`` is the
    starting world; ``encoding`` develops the genomes the algorithm breeds); descriptors:
    compute shape descriptors at each tell (off where the evaluator computes them, as the
    workers do); objectives: what selection optimises (``selection.Objective``s; the
    algorithm may add its own: ``afpo`` adds age); mode: the registered algorithm's name;
    grid: the MAP-Elites grid (``evolution.archive.Grid``) of an algorithm with an archive
    (``Algorithm.archive``), None for the others.
    """

    population_size: int = PAPER_POPULATION
    mode: str = "afpo"
    seed: int = 0
    evaluation: EvaluationSpec = field(default_factory=EvaluationSpec)
    objectives: tuple[Objective, ...] = PAPER_OBJECTIVES
    descriptors: bool = True
    grid: Grid | None = None

    def __post_init__(self) -> None:
        if self.mode not in ALGORITHMS:
            raise ValueError(f"mode must be one of {names()} (got {self.mode!r})")
        if self.evaluation.model not in models.names():
            raise ValueError(f"model must be one of {models.names()} (got {self.evaluation.model!r})")
        if self.population_size < 1:
            raise ValueError("population_size must be >= 1")
        # an objective given by name and direction alone is the registered one of that name
        resolved = tuple(o if o.value is not None else objective_named(o.name, o.direction)
                         for o in self.objectives)
        object.__setattr__(self, "objectives", resolved)
        if self.algorithm.archive:
            if self.grid is None:
                raise ValueError(f"algorithm {self.mode} keeps an archive: it needs a grid")
            if "distance" not in [o.name for o in resolved]:
                raise ValueError(f"algorithm {self.mode} keeps the farthest robots: distance must be an "
                                 "objective")
        elif self.grid is not None:
            raise ValueError(f"algorithm {self.mode} keeps no archive: it takes no grid")

    @property
    def encoding(self) -> EncodingConfig:
        """The encoding the algorithm develops and breeds genomes with."""
        return self.evaluation.encoding

    @property
    def algorithm(self) -> Algorithm:
        """The registered algorithm ``mode`` names."""
        return ALGORITHMS.get(self.mode)

    @property
    def selection_objectives(self) -> tuple[Objective, ...]:
        """The run's objectives, then those its algorithm adds."""
        return self.objectives + self.algorithm.objectives

    @property
    def computed_objectives(self) -> tuple[Objective, ...]:
        """The objectives computed for each evaluation: those of ``selection_objectives``
        with a value function (age, given at selection, is not)."""
        return tuple(o for o in self.selection_objectives if o.value is not None)

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON: the evaluation as its dict, each objective as [name, direction], the
        grid (where there is one) as ``Grid.to_json``."""
        data = {
            "population_size": self.population_size,
            "mode": self.mode,
            "seed": self.seed,
            "evaluation": self.evaluation.to_dict(),
            "objectives": [[o.name, o.direction] for o in self.objectives],
            "descriptors": self.descriptors,
        }
        if self.grid is not None:
            data["grid"] = self.grid.to_json()
        return data

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> EvolutionConfig:
        """Inverse of ``to_dict``; also reads the flat form stored before the evaluation had
        a carrier of its own (``environment``, ``youngs_modulus``, ``cycles``, ``encoding``,
        ``model``, ``max_seconds`` beside the algorithm's fields)."""
        data = dict(data)
        flat = {key: data.pop(key) for key in FLAT_EVALUATION_KEYS if key in data}
        if "evaluation" in data:
            data["evaluation"] = EvaluationSpec.from_dict(data["evaluation"])
        elif flat:
            defaults = EvaluationSpec()
            encoding = flat.get("encoding") or defaults.encoding.to_dict()
            data["evaluation"] = EvaluationSpec.from_dict({
                "environment": flat.get("environment", defaults.environment),
                "youngs_modulus": flat.get("youngs_modulus", defaults.youngs_modulus),
                "cycles": flat.get("cycles", defaults.cycles),
                "model": flat.get("model", defaults.model),
                "max_seconds": flat.get("max_seconds"),
                "encoding": encoding,
                "workspace": encoding["workspace"],
            })
        if "objectives" in data:
            data["objectives"] = tuple(objective_named(n, d) for n, d in data["objectives"])
        if data.get("grid") is not None:
            grid = data["grid"]
            data["grid"] = Grid(tuple(grid["measures"]), tuple(tuple(pair) for pair in grid["bounds"]),
                                tuple(grid["cells"]))
        return cls(**data)


FLAT_EVALUATION_KEYS = ("environment", "youngs_modulus", "cycles", "encoding", "model", "max_seconds")


class Evolution:
    """The ask/tell algorithm. Holds the population, the pending offspring and the RNG."""

    def __init__(self, config: EvolutionConfig, rng: np.random.Generator | None = None):
        self.config = config
        self.rng = rng if rng is not None else np.random.default_rng(config.seed)
        self.generation = 0  # generation of the individuals being (or last) evaluated
        self.next_id = 0
        self.environment = config.evaluation.environment
        self.population: list[Individual] = []  # evaluated survivors
        self.pending: list[Individual] = []  # this generation's individuals awaiting results
        self.started = False
        self.not_simulated = {"reused": 0, "empty": 0, "passive": 0}  # of this generation (not in the state)

    # ---- ask / tell ------------------------------------------------------------------------
    def ask(self) -> list[Individual]:
        """Individuals needing evaluation in ``self.environment`` (idempotent until told)."""
        if not self.pending:
            if self.started:
                self._breed()
            else:
                self.pending = [self.newcomer() for _ in range(self.config.population_size)]
                self.started = True
            self._fill_known()
        asked = [ind for ind in self.pending if not ind.evaluated]
        living = {ind.id for ind in self.population}
        if any(ind.id in living for ind in asked):
            raise RuntimeError(f"a survivor would be simulated again in {self.environment}")
        return asked

    def tell(self, outcomes: Sequence[Outcome] | Mapping[int, Outcome]) -> None:
        """Record outcomes (``evolution.outcome.Outcome``): a mapping {individual id: outcome}
        or a sequence in ``ask`` order. When every pending individual has its outcome,
        survivors are selected and the generation is complete. TypeError for anything but
        an ``Outcome``."""
        waiting = {ind.id: ind for ind in self.pending if not ind.evaluated}
        if not isinstance(outcomes, Mapping):
            asked = list(waiting.values())
            if len(outcomes) != len(asked):
                raise ValueError(f"expected {len(asked)} outcomes, got {len(outcomes)}")
            outcomes = {ind.id: value for ind, value in zip(asked, outcomes, strict=True)}
        for ind_id, outcome in outcomes.items():
            if ind_id not in waiting:
                raise KeyError(f"individual {ind_id} is not awaiting evaluation")
            if not isinstance(outcome, Outcome):
                raise TypeError(f"individual {ind_id}: an Outcome, not {type(outcome).__name__}")
            self._record(waiting[ind_id], outcome)
        if all(ind.evaluated for ind in self.pending):
            self._select()

    def reevaluate_all(self, environment: str) -> None:
        """Move the whole population into ``environment``: every living individual (and any
        pending offspring) is evaluated again there by the next ``ask``/``tell``."""
        self.environment = environment
        everyone = self.population + self.pending
        for ind in everyone:
            ind.clear_evaluation()
        self.population, self.pending = [], everyone
        self.started = True
        self.not_simulated = {"reused": 0, "empty": 0, "passive": 0}
        self._fill_known()

    @property
    def generation_complete(self) -> bool:
        return self.started and not self.pending

    # ---- internals -------------------------------------------------------------------------
    @property
    def batch_size(self) -> int:
        """How many new individuals a variation that breeds batches makes (``uniform_mutants``):
        the population size."""
        return self.config.population_size

    def _new_id(self) -> int:
        self.next_id += 1
        return self.next_id - 1

    def newcomer(self) -> Individual:
        """A random viable individual of age 0, born in this generation."""
        encoding = self.config.encoding
        genome, phenotype = random_viable(self.rng, encoding)
        newcomer = Individual(self._new_id(), None, self.generation, 0, genome)
        newcomer.developed(encoding, phenotype)
        return newcomer

    def mutant(self, parent: Individual) -> Individual:
        """A mutated child of ``parent``, born in this generation at its parent's age."""
        encoding = self.config.encoding
        genome, ops, _, phenotype = mutate_developed(
            parent.genome, parent.phenotype(encoding), self.rng, encoding
        )
        child = Individual(self._new_id(), parent.id, self.generation, parent.age, genome, mutations=ops)
        child.developed(encoding, phenotype)
        return child

    def _breed(self) -> None:
        self.generation += 1
        for ind in self.population:
            ind.age += 1
        offspring = [child for variation in self.config.algorithm.variations
                     for child in variation(self, list(self.population))]
        self.pending = offspring or [self.newcomer()]
        self.not_simulated = {"reused": 0, "empty": 0, "passive": 0}

    def _fill_known(self) -> None:
        """Evaluate without simulation: empty bodies and bodies the encoding rejects fail
        (both counted as ``empty`` in ``not_simulated``), a passive body (no active voxel)
        travels ``PASSIVE_DISTANCE`` (``passive``), known phenotypes reuse results."""
        known = {
            ind.phenotype(self.config.encoding).phenotype_hash(): ind
            for ind in self.population
            if ind.evaluated and ind.environment == self.environment
        }
        for ind in self.pending:
            if ind.evaluated:
                continue
            phenotype = ind.phenotype(self.config.encoding)
            twin = known.get(phenotype.phenotype_hash())
            if phenotype.voxel_count == 0:
                self._record(ind, Outcome.failure("empty body"))
                self.not_simulated["empty"] += 1
            elif self.config.encoding.rejects_invalid and not is_viable(phenotype, self.config.encoding):
                self._record(ind, Outcome.failure("invalid body"))
                self.not_simulated["empty"] += 1
            elif phenotype.active_share == 0:
                # no active voxel: it cannot move itself, and what a simulation would measure is
                # its fall (a tower toppling after settling travels 1.6 voxel lengths): 0
                self._record(ind, Outcome(PASSIVE_DISTANCE), describe=True)
                self.not_simulated["passive"] += 1
            elif twin is not None:
                self.not_simulated["reused"] += 1
                ind.objectives = dict(twin.objectives)
                ind.descriptors = None if twin.descriptors is None else dict(twin.descriptors)
                ind.environment, ind.stable, ind.error = self.environment, twin.stable, twin.error
                ind.evaluated_generation = self.generation

    def _record(self, ind: Individual, outcome: Outcome, describe: bool = False) -> None:
        """Give ``ind`` its ``outcome`` (the objectives computed from it, its descriptors);
        descriptors measured here with ``config.descriptors`` or ``describe`` (a passive
        body: no worker describes it)."""
        phenotype = ind.phenotype(self.config.encoding)
        ind.objectives = objective_values(self.config.computed_objectives, outcome, phenotype)
        ind.environment = self.environment
        ind.stable, ind.error = outcome.stable, outcome.error
        ind.descriptors = outcome.descriptors
        ind.evaluated_generation = self.generation
        if (self.config.descriptors or describe) and phenotype.voxel_count:
            from softevo.evolution.descriptors import describe_phenotype

            ind.descriptors = describe_phenotype(phenotype)

    def _select(self) -> None:
        combined = self.population + self.pending
        rows = [{**ind.objectives, "age": ind.age} for ind in combined]
        F = objective_matrix(rows, self.config.selection_objectives)
        valid = np.array([not ind.failed for ind in combined])
        # rows in id order, so "lower index" in select_survivors means "lower id"
        order = np.argsort([ind.id for ind in combined], kind="stable")
        ages = np.array([ind.age for ind in combined])
        candidates = Candidates(F[order], self.config.selection_objectives, ages[order], valid[order])
        grid = self.config.grid
        if self.config.algorithm.archive and grid is not None:
            candidates = candidates._replace(grid=grid, measures=self._measures(combined)[order])
        kept = self.config.algorithm.survival(candidates, self.config.population_size, self.rng)
        self.population = [combined[i] for i in order[kept]]
        self.pending = []

    def _measures(self, individuals: Sequence[Individual]) -> np.ndarray:
        """(n, k) float: each individual's values of the grid's k measures, as storage records
        them (``Individual.trait_values``), NaN where it has none."""
        names = self.config.grid.measures
        rows = []
        for ind in individuals:
            values = ind.trait_values(self.config.encoding, names)
            rows.append([np.nan if values.get(name) is None else float(values[name]) for name in names])
        return np.array(rows, dtype=float).reshape(len(individuals), len(names))

    # ---- state -----------------------------------------------------------------------------
    def state_to_dict(self) -> dict[str, Any]:
        return {
            "config": self.config.to_dict(),
            "rng": self.rng.bit_generator.state,
            "generation": self.generation,
            "next_id": self.next_id,
            "environment": self.environment,
            "started": self.started,
            "population": [ind.to_dict() for ind in self.population],
            "pending": [ind.to_dict() for ind in self.pending],
        }

    def state_to_json(self) -> str:
        return json.dumps(self.state_to_dict())

    @classmethod
    def from_state_dict(cls, state: Mapping[str, Any]) -> Evolution:
        config = EvolutionConfig.from_dict(state["config"])
        rng_state = state["rng"]
        bit_generator = getattr(np.random, rng_state["bit_generator"])()
        bit_generator.state = rng_state
        algo = cls(config, np.random.Generator(bit_generator))
        algo.generation = int(state["generation"])
        algo.next_id = int(state["next_id"])
        algo.environment = state["environment"]
        algo.started = bool(state["started"])
        algo.population = [Individual.from_dict(d) for d in state["population"]]
        algo.pending = [Individual.from_dict(d) for d in state["pending"]]
        return algo

    @classmethod
    def from_state_json(cls, text: str) -> Evolution:
        return cls.from_state_dict(json.loads(text))
