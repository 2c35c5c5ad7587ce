"""The phylogeny tree page of a run and the JSON it draws.

    /dashboard/runs/{id}/tree            the tree over generations (canvas), coloured by
                                         environment, the switch marked, survivors highlighted
    /dashboard/api/runs/{id}/tree        service.storage.run_tree.tree_sample: the surviving
                                         lineages and a bounded sample of extinct ones

The SQL picks what is drawn (at most ``max_survivors + extinct`` nodes), so a 30 x
9000-generation run draws a few thousand nodes; the browser only lays them out.
"""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, HTTPException, Query, Request
from fastapi.responses import HTMLResponse

from softevo.errors import UserError
from softevo.service.api.dashboard.pages import not_found, render
from softevo.service.api.deps import ConnectionDep
from softevo.service.api.params import RunId
from softevo.service.storage import runs as db_runs
from softevo.service.storage.run_tree import tree_sample

router = APIRouter()

MAX_SURVIVORS = 4000
MAX_EXTINCT = 600


@router.get("/runs/{run_id}/tree", response_class=HTMLResponse)
def tree_page(request: Request, run_id: RunId, conn: ConnectionDep) -> HTMLResponse:
    """A run's phylogeny drawn as a tree over generations."""
    if db_runs.run_status(conn, run_id) is None:
        return not_found(request, f"There is no run {run_id}.")
    return render(request, "tree.html", f"Run {run_id}: phylogeny", run_id=run_id)


@router.get("/api/runs/{run_id}/tree")
def tree(
    run_id: RunId,
    conn: ConnectionDep,
    max_survivors: Annotated[int, Query(ge=1, le=20_000)] = MAX_SURVIVORS,
    extinct: Annotated[int, Query(ge=0, le=5_000)] = MAX_EXTINCT,
) -> dict[str, Any]:
    """The nodes the tree draws (``service.storage.run_tree.tree_sample``)."""
    try:
        return tree_sample(conn, run_id, max_survivors=max_survivors, extinct=extinct)
    except UserError as exc:
        raise HTTPException(404, str(exc)) from exc
