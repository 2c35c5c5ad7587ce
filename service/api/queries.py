"""The REST API's read queries, by name: they live in the noun modules of ``service.db``
(``runs``, ``generations``, ``experiments``, ``individuals``) and are re-exported here for
the routes that still import them from this module.
"""

from __future__ import annotations

from softevo.service.db.experiments import (
    experiment_exists,
    experiment_generations,
    experiment_status,
    experiment_updated_at,
    list_experiments,
)
from softevo.service.db.generations import front, generations
from softevo.service.db.individuals import evaluations_of, individual, individual_context
from softevo.service.db.models import EVALUATION_FIELDS as EVALUATION_COLUMNS
from softevo.service.db.rows import finite
from softevo.service.db.runs import best_of_run, list_runs, run_detail, run_status

__all__ = [
    "EVALUATION_COLUMNS",
    "best_of_run",
    "evaluations_of",
    "experiment_exists",
    "experiment_generations",
    "experiment_status",
    "experiment_updated_at",
    "finite",
    "front",
    "generations",
    "individual",
    "individual_context",
    "list_experiments",
    "list_runs",
    "run_detail",
    "run_status",
]
