"""/individuals: one individual, its lineage, its recorded motion."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, HTTPException, Query, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import Response

from softevo.errors import UserError
from softevo.service.api.deps import BUSY, COMMON, NOT_FOUND, ExpensiveReadAccess, ServicesDep, client_of
from softevo.service.api.frames import __doc__ as FRAMES_FORMAT
from softevo.service.api.params import IndividualId
from softevo.service.api.schemas import ErrorOut, IndividualOut, LineageEntry, WorldName
from softevo.service.api.stored import stored_task_or_404
from softevo.service.storage.individuals import individual
from softevo.service.storage.rows import finite
from softevo.service.storage.status import lineage_records
from softevo.worker.tasks import EmptyBody

router = APIRouter(prefix="/individuals", tags=["individuals"], responses=COMMON)



def _with_connection(services, function, *args):
    with services.engine.connect() as conn:
        return function(conn, *args)


@router.get("/{individual_id}", response_model=IndividualOut, responses=NOT_FOUND)
def get_individual(individual_id: IndividualId, services: ServicesDep):
    """Genome, phenotype summary, objectives and descriptors (of the latest evaluation), and
    every evaluation (at birth, and again after an environment switch)."""
    found = _with_connection(services, individual, individual_id)
    if found is None:
        raise HTTPException(404, f"no individual {individual_id}")
    return found


@router.get("/{individual_id}/lineage", response_model=list[LineageEntry], responses=NOT_FOUND)
def lineage(individual_id: IndividualId, services: ServicesDep):
    """Ancestors, newest first (the individual itself at depth 0), to the root newcomer
    (``parent_id`` null); traits from each one's evaluation at birth."""

    try:
        return [finite(record) for record in lineage_records(services.engine, individual_id)]
    except UserError as exc:
        raise HTTPException(404, str(exc)) from exc


@router.get(
    "/{individual_id}/frames",
    response_class=Response,
    description=FRAMES_FORMAT,
    dependencies=[ExpensiveReadAccess],
    responses={
        200: {
            "content": {"application/octet-stream": {}},
            "description": "Recorded motion, little-endian float32 (format above)",
            "headers": {
                "X-Frames": {"schema": {"type": "integer"}, "description": "F"},
                "X-Voxels": {"schema": {"type": "integer"}, "description": "V"},
                "X-Time-Step": {"schema": {"type": "number"}, "description": "dt, seconds"},
                "X-Cache": {
                    "schema": {"type": "string"},
                    "description": "hit: from the cache; miss: simulated",
                },
            },
        },
        **NOT_FOUND,
        **BUSY,
        504: {"model": ErrorOut, "description": "The simulation took too long"},
    },
)
async def frames(
    individual_id: IndividualId,
    services: ServicesDep,
    request: Request,
    every: Annotated[int, Query(ge=10, le=1_000_000, description="record every n steps")] = 100,
    max_frames: Annotated[int, Query(ge=1, le=2000)] = 500,
    environment: Annotated[
        WorldName | None,
        Query(description="default: that of the individual's latest evaluation"),
    ] = None,
):
    """The individual's evaluated motion, simulated again with recording on (in a separate
    process: the API stays responsive), and kept in a cache (``SOFTEVO_FRAMES_CACHE_MB``)
    keyed by individual, world and recording settings. The body is the float32 format of
    ``service.api.frames``. 429 with ``Retry-After`` when ``SOFTEVO_BACKGROUND_QUEUE``
    simulations and reports are computing or waiting already."""
    task = await run_in_threadpool(stored_task_or_404, services, individual_id, environment)
    try:
        body, headers = await services.record_motion(task, every, max_frames, client=client_of(request))
    except TimeoutError as exc:  # SOFTEVO_FRAMES_TIMEOUT; the simulation has ended, its slot free
        raise HTTPException(504, "the simulation took too long") from exc
    except EmptyBody as exc:  # nothing to simulate
        raise HTTPException(404, f"individual {individual_id} has no motion: {exc}") from exc
    return Response(body, media_type="application/octet-stream", headers=headers)
