"""A local run: ask/evaluate/tell over generations with any evaluate function.

A generation, here as in the coordinator (``service.coordinator``), which asks through the
same ``ask_generation``:
1. ``ask_generation``: the algorithm breeds (``Evolution.ask``); at the first generation of
   a new environment of the ``Schedule``, ``Schedule.switch`` then moves survivors and
   offspring there (``reevaluate_all``) and all of them are asked again, to be evaluated in
   that same generation;
2. ``evaluations``: each asked individual's scenes (``evolution.scenes.evaluation_scenes``,
   one per part of a compound world such as ``land>water@0.250``) go to ``evaluate`` in one
   call, and the parts' outcomes are joined (``evolution.scenes.compound_outcome``);
3. ``Evolution.tell``; then ``on_generation`` sees the completed generation.

``evaluate`` receives a list of scene dicts (docs/spec.md section 1) and returns one result per
scene, in order: a ``sim.Result``, a dict with ``distance`` / ``stable`` / ``reason``, an
``Evaluation`` or an exception instance (see ``Evaluation.coerce``). ``sim.simulate_many``
fits as is. Nothing here touches processes, queues or databases.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from softevo.evolution.afpo import Evolution, EvolutionConfig
from softevo.evolution.individual import Individual
from softevo.evolution.scenes import compound_outcome, evaluation_scenes
from softevo.evolution.schedule import Schedule

Evaluate = Callable[[list[dict[str, Any]]], Sequence[Any]]
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
    config = algorithm.config
    return evaluation_scenes(
        ind.phenotype(config.encoding),
        algorithm.environment,
        config.youngs_modulus,
        config.cycles,
        model=config.model,
        max_seconds=config.max_seconds,
    )


def evaluations(algorithm: Evolution, asked: Sequence[Individual], evaluate: Evaluate) -> list[Any]:
    """One outcome per asked individual, in order, from one ``evaluate`` call over all their
    scenes; a crashing ``evaluate`` fails the batch (each outcome is its exception), never
    the run."""
    scenes = [individual_scenes(algorithm, ind) for ind in asked]
    flat = [scene for parts in scenes for scene in parts]
    try:
        outcomes = list(evaluate(flat)) if flat else []
    except Exception as exc:
        outcomes = [exc] * len(flat)
    joined, offset = [], 0
    for parts in scenes:
        joined.append(compound_outcome(outcomes[offset : offset + len(parts)]))
        offset += len(parts)
    return joined


def best_distance(algo: Evolution) -> float:
    """Largest distance among the current survivors (0 if none)."""
    distances = [ind.objectives["distance"] for ind in algo.population if ind.evaluated]
    return float(max(distances, default=0.0))


def generation_summary(algo: Evolution) -> dict[str, Any]:
    """One row of a run's history, after a completed generation: its number and world, the
    survivors' best and mean distance, how many survived and how many of those failed."""
    distances = [ind.objectives["distance"] for ind in algo.population if ind.evaluated]
    return {
        "generation": algo.generation,
        "environment": algo.environment,
        "best_distance": float(max(distances, default=0.0)),
        "mean_distance": float(sum(distances) / len(distances)) if distances else 0.0,
        "survivors": len(algo.population),
        "failed": sum(ind.failed for ind in algo.population),
    }


@dataclass(frozen=True, repr=False)
class LocalRun:
    """A finished local run: the algorithm at its end (``evolution.population``: the
    survivors with their objectives) and ``history``, one ``generation_summary`` row per
    generation."""

    evolution: Evolution
    history: list[dict[str, Any]]

    def __repr__(self) -> str:
        last = self.history[-1] if self.history else {}
        return (
            f"LocalRun(generations={len(self.history)}, environment={last.get('environment')!r}, "
            f"best_distance={last.get('best_distance', 0.0):.4g}, survivors={last.get('survivors', 0)})"
        )


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
    complete; returns the algorithm. ``schedule`` (default: ``config.environment`` for
    every generation) gives each generation's world, pure or compound; a generation that
    starts a new one is evaluated there whole, survivors included (``ask_generation``).
    ``on_generation`` is called after each completed generation."""
    algo = algo if algo is not None else Evolution(config)
    schedule = schedule or Schedule.static(config.environment)
    bar = _ProgressBar(generations + 1 - next_generation(algo)) if progress else None
    for generation in range(next_generation(algo), generations + 1):
        asked = ask_generation(algo, schedule, generation)
        algo.tell(evaluations(algo, asked, evaluate))
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
