"""A stored individual's evaluation task, for the routes that replay it: the frames
(``routes/individuals.py``) and the dashboard's body (``dashboard/body.py``)."""

from __future__ import annotations

from fastapi import HTTPException

from softevo.analysis import robots
from softevo.errors import UserError
from softevo.service.storage.individuals import individual_record
from softevo.worker.tasks import Task


def stored_task_or_404(services, individual_id: int, environment: str | None) -> Task:
    """The ``worker.tasks.Task`` of a stored individual's latest evaluation (in
    ``environment`` if given), as the coordinator built it (``analysis.robots.stored_task``);
    404 if there is no such individual or evaluation."""
    try:
        return robots.stored_task(individual_record(services.engine, individual_id), environment)
    except UserError as exc:
        raise HTTPException(404, str(exc)) from exc
