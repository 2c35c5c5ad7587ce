"""/runs/{id}/archive: a run's MAP-Elites archive after a generation, from its stored
evaluations (``service.storage.archive``); the same JSON as ``softevo archive RUN --json``."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, HTTPException, Query

from softevo.errors import UserError
from softevo.service.api.deps import COMMON, NOT_FOUND, ConnectionDep
from softevo.service.api.params import RunId, generation_query
from softevo.service.api.schemas_archive import ArchiveOut
from softevo.service.storage.archive import run_archive

router = APIRouter(prefix="/runs", tags=["archive"], responses=COMMON)


@router.get("/{run_id}/archive", response_model=ArchiveOut, responses=NOT_FOUND)
def archive(
    run_id: RunId,
    conn: ConnectionDep,
    generation: generation_query("the archive after this generation (default: the last stored)") = None,
    environment: Annotated[
        str | None, Query(max_length=20, description="the world's archive (default: the one evaluated then)")
    ] = None,
):
    """Per cell of the run's measures, its elite (the farthest evaluation whose measures fall
    in it), with the archive's coverage and QD score after every generation. 404 for an unknown
    run, a generation not stored or a world the run never evaluated in."""
    try:
        return run_archive(conn, run_id, generation, environment)
    except UserError as exc:
        raise HTTPException(404, str(exc)) from exc
