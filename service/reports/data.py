"""A stored experiment as the analyses' input: ``load_experiment(engine, id) ->
analysis.data.ExperimentData``, storage's rows (``service.storage.experiments``) read at the
generations the analyses compare and show (``analysis.matching.analysis_generations``)."""

from __future__ import annotations

from collections.abc import Iterable

from sqlalchemy import Engine

from softevo.analysis.data import ExperimentData, experiment_data
from softevo.analysis.matching import analysis_generations
from softevo.service.storage.experiments import read_experiment


def load_experiment(
    engine: Engine, experiment_id: int, generations: Iterable[int] = (), everything: bool = False
) -> ExperimentData:
    """Experiment ``experiment_id`` for the analyses (UserError if it does not exist or has
    no runs): its populations at generation 0, at each run's last stored generation, at
    every generation the analyses compare or show and at ``generations``, with every
    evaluation of their members; ``everything``: every population and every evaluation (the
    rows ``softevo export`` writes)."""
    frames = read_experiment(engine, experiment_id, generations, everything, shown=analysis_generations)
    return experiment_data(*frames)
