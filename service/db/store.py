"""The storage functions by their former home: re-exports of ``service.db.experiments``
(creation, ``resolve_experiment``), ``service.db.runs`` (``run_row``, ``resolve_runs``,
``reopen_runs``, ``set_run_status``, ``count_rows``), ``service.db.generations``
(``record_generation``) and ``service.db.individuals`` (``local_to_db_ids``).
"""

from __future__ import annotations

from softevo.service.db.experiments import NewRun, NewTreatment, create_experiment, resolve_experiment
from softevo.service.db.generations import GenerationRecord, insert_ignore, record_generation
from softevo.service.db.individuals import local_to_db_ids
from softevo.service.db.runs import count_rows, reopen_runs, resolve_runs, run_row, set_run_status

__all__ = [
    "GenerationRecord",
    "NewRun",
    "NewTreatment",
    "count_rows",
    "create_experiment",
    "insert_ignore",
    "local_to_db_ids",
    "record_generation",
    "reopen_runs",
    "resolve_experiment",
    "resolve_runs",
    "run_row",
    "set_run_status",
]
