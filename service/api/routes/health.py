"""GET /health: is the service up, how many workers, how many jobs wait, and if anything
stops the runs from going on, what."""

from __future__ import annotations

from fastapi import APIRouter
from fastapi.responses import JSONResponse

from softevo.service.api.deps import ServicesDep
from softevo.service.api.schemas import HealthOut
from softevo.service.storage.engine import database_reachable

router = APIRouter(tags=["health"])


@router.get(
    "/health",
    response_model=HealthOut,
    responses={
        503: {
            "model": HealthOut,
            "description": "Degraded: the database or Redis unreachable, the coordinator loop "
            "stopped, or jobs waiting with no worker alive (``reasons`` says which)",
        }
    },
)
def health(services: ServicesDep):
    """``{"status": "ok", "workers": n, "queued": n}`` and which executor and database state.
    503 (same body, status "degraded", ``reasons`` in words) when the database or Redis
    cannot be reached, when this process's coordinator loop has stopped, or when jobs wait
    and no worker is alive to take them."""
    database = "ok" if database_reachable(services.engine) else "unreachable"
    workers, queued, executor_ok = services.executor_status()
    loop = services.loop
    reasons = []
    if database != "ok":
        reasons.append("the database cannot be reached")
    if not executor_ok:
        reasons.append("Redis cannot be reached")
    if loop is not None and not loop.alive:
        reasons.append("the coordinator loop has stopped (see the log): restart softevo serve")
    if executor_ok and services.executor_kind == "rq" and queued > 0 and workers == 0:
        reasons.append(f"{queued} job(s) wait and no worker is alive: start softevo worker")
    body = HealthOut(
        status="degraded" if reasons else "ok",
        workers=workers,
        queued=queued,
        executor=services.executor_kind,
        database=database,
        coordinator=loop is not None and loop.alive,
        reasons=reasons,
    )
    if reasons:
        return JSONResponse(body.model_dump(), status_code=503)
    return body
