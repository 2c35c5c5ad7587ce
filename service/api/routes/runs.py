"""/runs: list (filters), one run, cancel, per-generation statistics, Pareto front, the best
individual per world."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, HTTPException, Query

from softevo.evolution.run_status import RunStatus
from softevo.service.api.deps import (
    COMMON,
    NOT_FOUND,
    UNAUTHORIZED,
    ConnectionDep,
    ServicesDep,
    WriteAccess,
)
from softevo.service.api.params import Offset, RunId, generation_query
from softevo.service.api.schemas import (
    MAX_INT32,
    BestOut,
    ErrorOut,
    FrontOut,
    GenerationOut,
    RunOut,
    RunStatusName,
    RunSummary,
)
from softevo.service.storage import generations as db_generations
from softevo.service.storage import runs as db_runs

router = APIRouter(prefix="/runs", tags=["runs"], responses=COMMON)

STOPPABLE = (RunStatus.PENDING, RunStatus.RUNNING)


@router.get("", response_model=list[RunSummary])
def list_runs(
    conn: ConnectionDep,
    experiment: Annotated[int | None, Query(ge=1, le=MAX_INT32)] = None,
    status: Annotated[RunStatusName | None, Query()] = None,
    limit: Annotated[int, Query(ge=1, le=10_000)] = 1000,
    offset: Offset = 0,
):
    """Runs in id order, optionally of one experiment and/or with one status."""
    return db_runs.list_runs(conn, experiment, status, limit, offset)


def _run_or_404(conn, run_id: int) -> dict:
    run = db_runs.run_detail(conn, run_id)
    if run is None:
        raise HTTPException(404, f"no run {run_id}")
    return run


@router.get("/{run_id}", response_model=RunOut, responses=NOT_FOUND)
def get_run(run_id: RunId, conn: ConnectionDep):
    """A run: status, last stored generation, treatment, best evaluation so far."""
    return _run_or_404(conn, run_id)


@router.post(
    "/{run_id}/cancel",
    response_model=RunOut,
    dependencies=[WriteAccess],
    responses={
        **UNAUTHORIZED,
        **NOT_FOUND,
        409: {"model": ErrorOut, "description": "The run already finished or failed"},
    },
)
def cancel(run_id: RunId, services: ServicesDep):
    """Cancel a pending or running run: nothing more is dispatched for it after the
    generation in flight. Cancelling a cancelled run changes nothing."""
    with services.engine.begin() as conn:
        status = db_runs.run_status(conn, run_id)
        if status is None:
            raise HTTPException(404, f"no run {run_id}")
        if status in (RunStatus.FINISHED.value, RunStatus.FAILED.value):
            raise HTTPException(409, f"run {run_id} is {status}: nothing to cancel")
        db_runs.set_run_status(conn, run_id, RunStatus.CANCELLED, only_from=STOPPABLE)
    services.cancel(run_id)
    with services.engine.connect() as conn:
        return _run_or_404(conn, run_id)


@router.get("/{run_id}/generations", response_model=list[GenerationOut], responses=NOT_FOUND)
def generations(run_id: RunId, conn: ConnectionDep):
    """Statistics of every stored generation, oldest first."""
    if db_runs.run_status(conn, run_id) is None:
        raise HTTPException(404, f"no run {run_id}")
    return db_generations.generations(conn, run_id)


@router.get("/{run_id}/front", response_model=FrontOut, responses=NOT_FOUND)
def front(
    run_id: RunId,
    conn: ConnectionDep,
    generation: generation_query("default: the latest stored") = None,
):
    """The non-dominated individuals (front rank 0 over distance, active share and voxel
    count) of the population kept at ``generation``."""
    if db_runs.run_status(conn, run_id) is None:
        raise HTTPException(404, f"no run {run_id}")
    found = db_generations.front(conn, run_id, generation)
    if found is None:
        which = "any generation" if generation is None else f"generation {generation}"
        raise HTTPException(404, f"run {run_id} has not stored {which} yet")
    return found


@router.get("/{run_id}/best", response_model=list[BestOut], responses=NOT_FOUND)
def best(run_id: RunId, conn: ConnectionDep):
    """The run's best evaluation (greatest distance) in each world it was evaluated in, in
    the order the run met them (its last world last; a land -> water run has two); empty
    before any evaluation. The same as ``softevo best RUN``."""
    if db_runs.run_status(conn, run_id) is None:
        raise HTTPException(404, f"no run {run_id}")
    return db_runs.best_per_world(conn, run_id)
