"""/experiments: submit (treatments or a preset), list, one experiment, its report."""

from __future__ import annotations

import importlib
import logging
from pathlib import Path as FilePath
from typing import Annotated

from fastapi import APIRouter, HTTPException, Path, Query, status
from fastapi.responses import FileResponse

from service.api import queries
from service.api.deps import (
    COMMON,
    NOT_FOUND,
    UNAUTHORIZED,
    ConnectionDep,
    ServicesDep,
    WriteAccess,
)
from service.api.schemas import (
    MAX_INT32,
    ErrorOut,
    ExperimentCreated,
    ExperimentIn,
    ExperimentOut,
    ExperimentRequest,
    PresetIn,
)
from service.errors import UserError

router = APIRouter(prefix="/experiments", tags=["experiments"], responses=COMMON)
log = logging.getLogger("softevo.api")

ExperimentId = Annotated[int, Path(ge=1, le=MAX_INT32, description="experiment id")]
REPORT_FILE = "report.html"


def _treatments(body: ExperimentIn):
    """The request's treatments as ``service.treatments.Treatment`` (their own checks apply:
    switch_at within the generations and for a transition only)."""
    from service.treatments import Treatment

    treatments = [
        Treatment(
            t.environment,
            t.stiffness_mpa,
            name=t.name or "",
            switch_at=t.switch_at,
            population=t.population,
            generations=t.generations,
            workspace=tuple(t.workspace),
            cycles=t.cycles,
            repetitions=t.repetitions,
            seed=t.seed,
            algorithm=t.algorithm,
        )
        for t in body.treatments
    ]
    names = [t.name for t in treatments]
    duplicates = sorted({name for name in names if names.count(name) > 1})
    if duplicates:
        raise UserError(
            f"treatment names must differ within an experiment: {', '.join(duplicates)} (give each a name)"
        )
    return treatments


@router.post(
    "",
    status_code=status.HTTP_201_CREATED,
    response_model=ExperimentCreated,
    dependencies=[WriteAccess],
    responses=UNAUTHORIZED,
)
def submit(body: ExperimentRequest, services: ServicesDep) -> ExperimentCreated:
    """Create an experiment with one pending run per treatment repetition; the coordinator
    starts them. Body: ``{"name", "treatments": [...]}`` or ``{"preset": "paper", "scale"}``.
    """
    from service.experiments import create
    from service.treatments import paper_grid

    if isinstance(body, PresetIn):
        treatments = paper_grid(body.scale, repetitions=body.repetitions, seed=body.seed)
        name = body.name or f"{body.preset}-{body.scale}"
        experiment_id, run_ids = create(
            services.engine, name, treatments, preset=body.preset, scale=body.scale
        )
    else:
        experiment_id, run_ids = create(services.engine, body.name, _treatments(body))
    services.wake()
    return ExperimentCreated(id=experiment_id, runs=run_ids)


@router.get("", response_model=list[ExperimentOut])
def list_experiments(
    conn: ConnectionDep,
    limit: Annotated[int, Query(ge=1, le=1000)] = 100,
    offset: Annotated[int, Query(ge=0, le=MAX_INT32)] = 0,
):
    """Experiments, oldest first, with the status and progress of each run."""
    return queries.list_experiments(conn, limit=limit, offset=offset)


@router.get("/{experiment_id}", response_model=ExperimentOut, responses=NOT_FOUND)
def get_experiment(experiment_id: ExperimentId, conn: ConnectionDep):
    """One experiment: its runs' status and progress."""
    found = queries.list_experiments(conn, experiment_id=experiment_id)
    if not found:
        raise HTTPException(404, f"no experiment {experiment_id}")
    return found[0]


def _report_generator():
    """``analysis.report.write_report`` if issue 6's module is installed, else None."""
    try:
        module = importlib.import_module("analysis.report")
    except ImportError:
        return None
    return getattr(module, "write_report", None)


@router.get(
    "/{experiment_id}/report",
    response_class=FileResponse,
    responses={
        200: {"content": {"text/html": {}}, "description": "The experiment's HTML report"},
        **NOT_FOUND,
        500: {"model": ErrorOut, "description": "The report could not be written"},
    },
)
def report(experiment_id: ExperimentId, conn: ConnectionDep, services: ServicesDep):
    """The experiment's HTML report (figures, statistics, settings; issue 6), written on the
    first request into ``SOFTEVO_REPORTS/experiment-<id>/`` and served from there after.
    404 while no report exists and no report writer is installed."""
    if not queries.experiment_exists(conn, experiment_id):
        raise HTTPException(404, f"no experiment {experiment_id}")
    out_dir = FilePath(services.settings.reports) / f"experiment-{experiment_id}"
    html = out_dir / REPORT_FILE
    if not html.is_file():
        write_report = _report_generator()
        if write_report is None:
            raise HTTPException(
                404,
                f"no report for experiment {experiment_id} yet: the report writer "
                "(analysis.report, issue 6) is not installed; `softevo report` makes one",
            )
        try:
            written = write_report(services.engine, experiment_id, out_dir)
        except Exception as exc:
            log.exception("report of experiment %d failed", experiment_id)
            raise HTTPException(500, f"the report could not be written: {exc}") from exc
        html = _html_in(written, out_dir) or html
        if not html.is_file():
            raise HTTPException(500, "the report writer wrote no HTML file")
    return FileResponse(html, media_type="text/html")


def _html_in(written, out_dir: FilePath) -> FilePath | None:
    """The HTML file among what the writer returned (a path, or paths) or wrote."""
    candidates = written if isinstance(written, list | tuple) else [written]
    for candidate in candidates:
        if isinstance(candidate, str | FilePath) and str(candidate).endswith(".html"):
            return FilePath(candidate)
    found = sorted(out_dir.glob("*.html"))
    return found[0] if found else None
