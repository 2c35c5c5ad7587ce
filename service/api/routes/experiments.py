"""/experiments: submit (treatments or a preset), list, one experiment, its report."""

from __future__ import annotations

import logging
import time
from datetime import UTC, datetime
from pathlib import Path as FilePath
from typing import Annotated

from fastapi import APIRouter, HTTPException, Query, Request, status
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import FileResponse

from softevo.errors import UserError
from softevo.service.api.deps import (
    BUSY,
    COMMON,
    NOT_FOUND,
    UNAUTHORIZED,
    ConnectionDep,
    ExpensiveReadAccess,
    ServicesDep,
    WriteAccess,
    client_of,
)
from softevo.service.api.params import ExperimentId, Offset
from softevo.service.api.requests import request_treatments
from softevo.service.api.schemas import (
    MAX_INT32,
    ErrorOut,
    ExperimentCreated,
    ExperimentOut,
    ExperimentRequest,
    PresetIn,
)
from softevo.service.runs.submit import create
from softevo.service.storage import experiments as db_experiments
from softevo.service.storage import runs as db_runs

router = APIRouter(prefix="/experiments", tags=["experiments"], responses=COMMON)
log = logging.getLogger("softevo.api")

REPORT_FILE = "report.html"
REPORT_FAILED = (
    "the report could not be written (the server's log says why); "
    "it is tried again once the experiment changes"
)
_NEVER = object()
# Pages: at most 100 experiments x 200 runs in one listing (about 5 MB), 1000 runs of one
MAX_EXPERIMENTS_PAGE = 100
MAX_LISTED_RUNS_PAGE = 200
MAX_RUNS_PAGE = 1000
RUNS_PAGE = db_experiments.RUNS_PAGE


@router.post(
    "",
    status_code=status.HTTP_201_CREATED,
    response_model=ExperimentCreated,
    dependencies=[WriteAccess],
    responses={
        **UNAUTHORIZED,
        400: {"model": ErrorOut, "description": "The body is not JSON"},
        413: {"model": ErrorOut, "description": "The body is larger than SOFTEVO_MAX_BODY_BYTES"},
        503: {"model": ErrorOut, "description": "Redis cannot be reached: nothing is stored"},
    },
)
def submit(body: ExperimentRequest, services: ServicesDep) -> ExperimentCreated:
    """Create an experiment with one pending run per treatment repetition; the coordinator
    picks them up within a second. Body: ``{"name", "treatments": [...]}`` or
    ``{"preset": "paper", "scale"}``. 422 (with the figure) for more runs than
    ``SOFTEVO_MAX_RUNS_PER_REQUEST``, or more voxel-steps (population x generations x
    repetitions x workspace voxels x steps per evaluation) than
    ``SOFTEVO_MAX_REQUEST_VOXEL_STEPS``, or than ``SOFTEVO_MAX_SERVER_VOXEL_STEPS`` together
    with the unfinished runs. 503 (nothing stored) while the server's Redis cannot be
    reached: no worker could take the runs' jobs, and they would wait pending unsaid."""
    treatments = request_treatments(body)
    if not services.redis_reachable():
        raise HTTPException(
            503, "Redis cannot be reached (SOFTEVO_REDIS_URL), so no worker could run this experiment: "
            "it is not stored; start Redis and send it again (softevo serve goes on by itself), or "
            "unset SOFTEVO_REDIS_URL to evaluate in the server's own processes",
            headers={"Retry-After": "5"},
        )
    if isinstance(body, PresetIn):
        name = body.name or f"{body.preset}-{body.scale}"
        experiment_id, run_ids = create(
            services.engine, name, treatments, body.preset, body.scale, settings=services.settings
        )
    else:
        experiment_id, run_ids = create(services.engine, body.name, treatments, settings=services.settings)
    return ExperimentCreated(id=experiment_id, runs=run_ids)


RunsLimit = Annotated[
    int, Query(ge=0, le=MAX_RUNS_PAGE, description="runs listed (0: none, only the counts)")
]
ListedRunsLimit = Annotated[
    int,
    Query(ge=0, le=MAX_LISTED_RUNS_PAGE, description="runs listed per experiment (0: none, only the counts)"),
]
RunsOffset = Annotated[int, Query(ge=0, le=MAX_INT32, description="runs of each experiment skipped")]


@router.get("", response_model=list[ExperimentOut])
def list_experiments(
    conn: ConnectionDep,
    limit: Annotated[int, Query(ge=1, le=MAX_EXPERIMENTS_PAGE)] = 100,
    offset: Offset = 0,
    runs_limit: ListedRunsLimit = RUNS_PAGE,
    runs_offset: RunsOffset = 0,
    newest_first: bool = False,
):
    """Experiments, oldest first (``newest_first``: newest), each with its status, progress and
    ``runs_total`` over all its runs and a page of its runs (``runs_limit`` from the
    ``runs_offset``-th): at most 100 x 200 runs in one answer."""
    return db_experiments.list_experiments(
        conn, limit=limit, offset=offset, runs_limit=runs_limit, runs_offset=runs_offset,
        newest_first=newest_first,
    )  # fmt: skip


@router.get("/{experiment_id}", response_model=ExperimentOut, responses=NOT_FOUND)
def get_experiment(
    experiment_id: ExperimentId,
    conn: ConnectionDep,
    runs_limit: RunsLimit = RUNS_PAGE,
    runs_offset: RunsOffset = 0,
):
    """One experiment: its status and progress, ``runs_total`` and a page of its runs."""
    found = db_experiments.list_experiments(
        conn, experiment_id=experiment_id, runs_limit=runs_limit, runs_offset=runs_offset
    )
    if not found:
        raise HTTPException(404, f"no experiment {experiment_id}")
    return found[0]


def _stale(html: FilePath, updated: datetime | None, live: bool, interval: float) -> bool:
    """Whether the report should be written again: it is missing, or it misses generations
    stored after it was written and (while a run of the experiment is live) it is older than
    ``interval`` seconds (``SOFTEVO_REPORT_INTERVAL``)."""
    if not html.is_file():
        return True
    if updated is None:
        return False
    if updated.tzinfo is None:  # SQLite keeps UTC without its zone
        updated = updated.replace(tzinfo=UTC)
    written = html.stat().st_mtime
    if updated.timestamp() <= written:
        return False
    return not live or time.time() - written >= interval


@router.get(
    "/{experiment_id}/report",
    response_class=FileResponse,
    dependencies=[ExpensiveReadAccess],
    responses={
        200: {"content": {"text/html": {}}, "description": "The experiment's HTML report"},
        **NOT_FOUND,
        **BUSY,
        500: {"model": ErrorOut, "description": "The report could not be written"},
        504: {"model": ErrorOut, "description": "Writing the report took too long"},
    },
)
async def report(experiment_id: ExperimentId, services: ServicesDep, request: Request):
    """The experiment's self-contained HTML report (figures, statistics, settings).

    Written by ``service.reports.report.write_report`` into ``$SOFTEVO_REPORTS/experiment-<id>/``
    on the first request, again when runs have stored generations since (while a run is
    live, at most once per ``SOFTEVO_REPORT_INTERVAL`` seconds), and served from there. 404
    while the experiment has no stored generation; 429 with ``Retry-After`` when
    ``SOFTEVO_BACKGROUND_QUEUE`` simulations and reports are computing or waiting already.
    A report that failed is 500 again, without being written again, until a run of the
    experiment changes."""
    updated, live = await run_in_threadpool(_last_update, services, experiment_id)
    out_dir = FilePath(services.settings.reports) / f"experiment-{experiment_id}"
    html = out_dir / REPORT_FILE
    if _stale(html, updated, live, services.settings.report_interval):
        if services.report_failures.get(experiment_id, _NEVER) == updated:
            raise HTTPException(500, REPORT_FAILED)  # failed already, nothing changed since
        try:
            written = await services.write_report(experiment_id, out_dir, client=client_of(request))
        except TimeoutError as exc:  # SOFTEVO_REPORT_TIMEOUT; the writer has ended, its slot free
            raise HTTPException(504, "writing the report took too long; try again") from exc
        except UserError as exc:  # e.g. no generation stored yet
            raise HTTPException(404, f"no report for experiment {experiment_id}: {exc}") from exc
        except Exception as exc:  # the log has why; the answer says nothing of the writer's text
            log.exception("report of experiment %d failed", experiment_id)
            services.report_failures[experiment_id] = updated
            raise HTTPException(500, REPORT_FAILED) from exc
        html = FilePath(getattr(written, "html", html))
        if not html.is_file():
            raise HTTPException(500, "the report writer wrote no HTML file")
    return FileResponse(html, media_type="text/html")


def _last_update(services, experiment_id: int) -> tuple[datetime | None, bool]:
    """Latest update of the experiment's runs and whether one of them is pending or running;
    404 if there is no such experiment or it has no stored generation (nothing to report)."""
    with services.engine.connect() as conn:
        if not db_experiments.experiment_exists(conn, experiment_id):
            raise HTTPException(404, f"no experiment {experiment_id}")
        if db_experiments.experiment_generations(conn, experiment_id) == 0:
            raise HTTPException(404, f"no report for experiment {experiment_id}: no generation stored yet")
        live = any(db_runs.list_runs(conn, experiment_id, status, 1) for status in ("running", "pending"))
        return db_experiments.experiment_updated_at(conn, experiment_id), bool(live)
