"""``GET /experiments/{id}/analysis``: the experiment page's data (treatments side by side).

An expensive read (``service.api.expensive``): the experiment is read and its statistics
computed in the background process, at most ``SOFTEVO_BACKGROUND_QUEUE`` such reads at
once (429 past it), each for at most ``SOFTEVO_REPORT_TIMEOUT`` seconds (504), behind
``SOFTEVO_READ_TOKEN`` when it is set. The answer is cached until a run of the experiment
changes (the key holds its last update), so polling a finished experiment computes nothing.
"""

from __future__ import annotations

from fastapi import APIRouter, HTTPException, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import Response

from softevo.errors import UserError
from softevo.service.api.deps import BUSY, COMMON, NOT_FOUND, ExpensiveReadAccess, ServicesDep, client_of
from softevo.service.api.params import ExperimentId
from softevo.service.api.schemas import ErrorOut
from softevo.service.api.schemas_analysis import ExperimentAnalysisOut
from softevo.service.reports.experiment import analysis_json
from softevo.service.storage import experiments as db_experiments

router = APIRouter(prefix="/experiments", tags=["experiments"], responses=COMMON)


def _last_update(services, experiment_id: int):
    """When a run of the experiment last changed; 404 without the experiment or before its
    first stored generation."""
    with services.engine.connect() as conn:
        if not db_experiments.experiment_exists(conn, experiment_id):
            raise HTTPException(404, f"no experiment {experiment_id}")
        if db_experiments.experiment_generations(conn, experiment_id) == 0:
            raise HTTPException(404, f"experiment {experiment_id} has no stored generation yet")
        return db_experiments.experiment_updated_at(conn, experiment_id)


@router.get(
    "/{experiment_id}/analysis",
    dependencies=[ExpensiveReadAccess],
    response_class=Response,
    responses={
        200: {"model": ExperimentAnalysisOut, "description": "The treatments side by side"},
        **NOT_FOUND,
        **BUSY,
        504: {"model": ErrorOut, "description": "Computing took longer than SOFTEVO_REPORT_TIMEOUT"},
    },
)
async def analysis(
    experiment_id: ExperimentId,
    services: ServicesDep,
    request: Request,
) -> Response:
    """Fitness curves (mean best distance over runs with 95% t intervals), the aggregated
    Pareto fronts (distance against active share), the descriptors (one value per run) and
    the statistics table (families, tests, Bonferroni, A12) of every treatment, with its runs
    (``service.reports.report.experiment``)."""
    updated = await run_in_threadpool(_last_update, services, experiment_id)
    key = ("analysis", experiment_id, str(updated))
    hit = services.reads.cached(key) is not None
    try:
        body = await services.reads.compute(
            key, analysis_json, services.settings.db, experiment_id,
            timeout=services.settings.report_timeout, client=client_of(request),
        )  # fmt: skip
    except TimeoutError as exc:
        raise HTTPException(504, "computing the analysis took too long; try again") from exc
    except UserError as exc:
        raise HTTPException(404, str(exc)) from exc
    return Response(body, media_type="application/json", headers={"X-Cache": "hit" if hit else "miss"})
