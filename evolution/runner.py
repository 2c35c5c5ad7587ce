"""A local run: ask/evaluate/tell over generations with one evaluate function.

A generation, here as in the coordinator (``service.runs.coordinator``), which asks and
tells through the same ``ask_generation`` and ``tell_generation``:
1. ``ask_generation``: the algorithm breeds (``Evolution.ask``); at the first generation of
   a new environment of the ``Schedule``, ``Schedule.switch`` then moves survivors and
   offspring there (``reevaluate_all``) and all of them are asked again, to be evaluated in
   that same generation;
2. ``evaluate(algorithm, asked, generation)`` gives each asked individual's
   ``evolution.outcome.Outcome`` by id: the workers' ``worker.evaluate.evaluate_generation``
   (``softevo.evolve``), which splits a compound world into its parts and combines their
   outcomes as every executor does;
3. ``tell_generation``; then ``on_generation`` sees the completed generation.

Nothing here touches processes, queues or databases.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from softevo.evolution import environments, traits
from softevo.evolution.algorithm import Evolution, EvolutionConfig
from softevo.evolution.individual import Individual
from softevo.evolution.outcome import Outcome
from softevo.evolution.schedule import Schedule

Evaluate = Callable[[Evolution, list[Individual], int], Mapping[int, Outcome]]
OnGeneration = Callable[[Evolution], None]


def ask_generation(algorithm: Evolution, schedule: Schedule, generation: int) -> list[Individual]:
    """The individuals to evaluate at ``generation``: ask (breeding a new generation once the
    last is complete), switch to the schedule's world of ``generation`` if the algorithm is
    in another (then every survivor and offspring is asked again there). RuntimeError if the
    algorithm is not at ``generation`` after asking."""
    asked = algorithm.ask()
    if schedule.switch(algorithm, generation):
        asked = algorithm.ask()
    if algorithm.generation != generation:
        raise RuntimeError(f"algorithm at generation {algorithm.generation}, run at {generation}")
    return asked


def individual_scenes(algorithm: Evolution, ind: Individual) -> list[dict[str, Any]]:
    """The scenes that evaluate ``ind`` in the algorithm's current world (one per part of a
    compound world), with the run's stiffness, cycles, model and cap on seconds."""
    spec = algorithm.config.evaluation.in_world(algorithm.environment)
    return spec.scenes(ind.phenotype(spec.encoding))


def tell_generation(
    algorithm: Evolution, asked: Sequence[Individual], outcomes: Mapping[int, Outcome]
) -> None:
    """Tell the algorithm the outcomes of the asked individuals ({id: ``Outcome``}; an
    outcome's descriptors become its individual's), then each registered trait
    (``evolution.traits.computed``) joins the descriptors."""
    generation, evaluated = algorithm.generation, list(algorithm.pending)
    told = {}
    for ind in asked:
        told[ind.id] = outcomes[ind.id]  # KeyError for a lost outcome: a bug, never a silent failure
    algorithm.tell(told)
    # the registered traits (evolution.traits), measured on the phenotype of every individual
    # evaluated at this generation: asked, or evaluated without a simulation (a twin, a passive body)
    for ind in evaluated:
        extra = traits.computed(ind.phenotype(algorithm.config.encoding))
        if extra and ind.evaluated_generation == generation:
            ind.descriptors = {**(ind.descriptors or {}), **extra}


def best_distance(algo: Evolution) -> float:
    """Largest distance among the current survivors (0 if none)."""
    distances = [ind.objectives["distance"] for ind in algo.population if ind.evaluated]
    return float(max(distances, default=0.0))


def generation_summary(algo: Evolution) -> dict[str, Any]:
    """One row of a run's history, after a completed generation: its number and world, the
    survivors' best and mean distance, how many survived and how many of those failed, and
    ``members``: each survivor's id and distance, by id (``softevo run`` stores the same)."""
    distances = [ind.objectives["distance"] for ind in algo.population if ind.evaluated]
    return {
        "generation": algo.generation,
        "environment": algo.environment,
        "best_distance": float(max(distances, default=0.0)),
        "mean_distance": float(sum(distances) / len(distances)) if distances else 0.0,
        "survivors": len(algo.population),
        "failed": sum(ind.failed for ind in algo.population),
        "members": sorted((ind.id, float(ind.objectives["distance"])) for ind in algo.population
                          if ind.evaluated),
    }


@dataclass(frozen=True)
class Best:
    """The best individual of a run in one pure world: ``distance`` (voxel lengths) and the
    ``scene`` (a dict ``softevo.simulate`` runs) that reproduces it, its ``individual``,
    the ``generation`` it was best at and its ``world``."""

    world: str
    generation: int
    distance: float
    individual: Individual = field(repr=False)
    scene: dict[str, Any] = field(repr=False)


@dataclass(frozen=True, repr=False)
class LocalRun:
    """A finished local run: the algorithm at its end (``evolution.population``: the
    survivors with their objectives), ``history``, one ``generation_summary`` row per
    generation, and ``best(world)``: the best individual seen in each pure world."""

    evolution: Evolution
    history: list[dict[str, Any]]
    bests: dict[str, Best] = field(default_factory=dict)

    def best(self, world: str | None = None) -> Best:
        """The best individual evaluated in ``world`` (default: the last world of the run),
        with its ``distance`` and ``scene``; KeyError naming the worlds seen for another."""
        world = world if world is not None else self.history[-1]["environment"] if self.history else None
        if world not in self.bests:
            seen = ", ".join(self.bests) or "none"
            raise KeyError(f"no individual evaluated in {world!r}; worlds seen: {seen}")
        return self.bests[world]

    def __repr__(self) -> str:
        last = self.history[-1] if self.history else {}
        return (
            f"LocalRun(generations={len(self.history)}, environment={last.get('environment')!r}, "
            f"best_distance={last.get('best_distance', 0.0):.4g}, survivors={last.get('survivors', 0)})"
        )


def record_best(bests: dict[str, Best], algorithm: Evolution) -> None:
    """Keep in ``bests`` the best survivor of the algorithm's current pure world if it beats
    the one kept (the first found wins ties)."""
    world = algorithm.environment
    if environments.is_compound(world):
        return
    scored = [ind for ind in algorithm.population if ind.evaluated and not ind.failed]
    if not scored:
        return
    top = max(scored, key=lambda ind: ind.objectives["distance"])
    distance = float(top.objectives["distance"])
    if world in bests and bests[world].distance >= distance:
        return
    spec = algorithm.config.evaluation.in_world(world)
    (scene,) = spec.scenes(top.phenotype(spec.encoding))
    bests[world] = Best(world, algorithm.generation, distance, top, scene)


def next_generation(algorithm: Evolution) -> int:
    """The generation ``ask_generation`` does next: 0 before the first, the one in progress,
    or the one after a completed generation."""
    return algorithm.generation + 1 if algorithm.generation_complete else algorithm.generation


def run(
    config: EvolutionConfig,
    evaluate: Evaluate,
    generations: int,
    *,
    schedule: Schedule | None = None,
    algo: Evolution | None = None,
    on_generation: OnGeneration | None = None,
    progress: bool = False,
) -> Evolution:
    """Run (or continue ``algo``) until ``generations`` generations after generation 0 are
    complete; returns the algorithm. Each generation's asked individuals go to ``evaluate``
    (the workers' ``worker.evaluate.evaluate_generation``, or one with a stand-in simulator
    in tests). ``schedule`` (default: the config's world for every generation) gives each
    generation's world, pure or compound; a generation that starts a new one is evaluated
    there whole, survivors included (``ask_generation``). ``on_generation`` is called after
    each completed generation."""
    algo = algo if algo is not None else Evolution(config)
    schedule = schedule or Schedule.static(config.evaluation.environment)
    bar = _ProgressBar(generations + 1 - next_generation(algo)) if progress else None
    for generation in range(next_generation(algo), generations + 1):
        asked = ask_generation(algo, schedule, generation)
        tell_generation(algo, asked, evaluate(algo, asked, generation))
        if on_generation is not None:
            on_generation(algo)
        if bar is not None:
            bar.advance(best_distance(algo))
    if bar is not None:
        bar.close()
    return algo


class _ProgressBar:
    """A rich progress bar over generations showing the best distance."""

    def __init__(self, total: int):
        from rich.progress import Progress

        self._progress = Progress(*Progress.get_default_columns(), "{task.fields[best]}")
        self._task = self._progress.add_task("generations", total=total, best="")
        self._progress.start()

    def advance(self, best: float) -> None:
        self._progress.update(self._task, advance=1, best=f"best {best:.3f}")

    def close(self) -> None:
        self._progress.stop()
