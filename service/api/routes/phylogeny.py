"""/runs/{id}/phylogeny and /runs/{id}/exaptation: a run's tree, page by page, and what
survived its environment transition (``docs/sql.md`` gives both as SQL)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, HTTPException, Query

from softevo.errors import UserError
from softevo.service.api.deps import COMMON, NOT_FOUND, ConnectionDep
from softevo.service.api.params import Offset, RunId, generation_query
from softevo.service.api.schemas_phylogeny import ExaptationOut, PhylogenyPage
from softevo.service.storage.exaptation import exaptation as run_exaptation
from softevo.service.storage.run_tree import run_phylogeny

router = APIRouter(prefix="/runs", tags=["phylogeny"], responses=COMMON)



@router.get("/{run_id}/phylogeny", response_model=PhylogenyPage, responses=NOT_FOUND)
def phylogeny(
    run_id: RunId,
    conn: ConnectionDep,
    generation: generation_query("the tree as it stood at this generation") = None,
    limit: Annotated[int, Query(ge=1, le=10_000)] = 1000,
    offset: Offset = 0,
):
    """Every individual of the run in id order: parent, generation born, last generation
    kept, environment and objectives of its first evaluation."""
    try:
        total, rows = run_phylogeny(conn, run_id, generation, limit=limit, offset=offset)
    except UserError as exc:
        raise HTTPException(404, str(exc)) from exc
    return {"run_id": run_id, "total": total, "limit": limit, "offset": offset, "individuals": rows}


@router.get("/{run_id}/exaptation", response_model=ExaptationOut, responses=NOT_FOUND)
def exaptation(
    run_id: RunId,
    conn: ConnectionDep,
    limit: Annotated[int, Query(ge=1, le=1000, description="surviving lines per page")] = 100,
    offset: Offset = 0,
):
    """For a transition run: the founders (kept at switch_at - 1), how many of their lines
    reach the last stored generation, the final population's root newcomers, and per
    surviving line the traits of the founder, at the switch and at the end with the birth
    generation each first changed. 404 for an unknown run or one without a transition."""
    try:
        summary = run_exaptation(conn, run_id, limit=limit, offset=offset)
    except UserError as exc:
        raise HTTPException(404, str(exc)) from exc
    return {**summary, "limit": limit, "offset": offset}
