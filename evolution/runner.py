"""A local run: drive ask/tell over generations with any evaluate function.

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
from softevo.evolution.schedule import Schedule

Evaluate = Callable[[list[dict[str, Any]]], Sequence[Any]]
OnGeneration = Callable[[Evolution], None]


def evaluate_pending(algo: Evolution, evaluate: Evaluate) -> list[Individual]:
    """Ask, evaluate the scenes in one call, tell; returns the individuals evaluated."""
    asked = algo.ask()
    if asked:
        try:
            results = list(evaluate([algo.scene(ind) for ind in asked]))
        except Exception as exc:  # a crashing evaluator fails this batch, never the run
            results = [exc] * len(asked)
        algo.tell(results)
    else:
        algo.tell([])
    return asked


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
    every generation) switches environments (``Schedule.switch``): when the generation about
    to start belongs to a new environment, the whole population is re-evaluated there first.
    ``on_generation`` is called after each completed generation."""
    algo = algo if algo is not None else Evolution(config)
    schedule = schedule or Schedule.static(config.environment)
    if not algo.started:
        algo.environment = schedule.environment_at(0)
    bar = _ProgressBar(generations + 1) if progress else None
    while not (algo.generation_complete and algo.generation >= generations):
        if algo.generation_complete and schedule.switch(algo, algo.generation + 1):
            while algo.pending:
                evaluate_pending(algo, evaluate)
        evaluate_pending(algo, evaluate)
        if algo.generation_complete:
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
