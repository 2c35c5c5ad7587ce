"""GET /health: is the service up, how many workers, how many jobs wait."""

from __future__ import annotations

from fastapi import APIRouter
from fastapi.responses import JSONResponse

from softevo.service.api.deps import ServicesDep
from softevo.service.api.schemas import HealthOut
from softevo.service.db.engine import database_reachable

router = APIRouter(tags=["health"])


@router.get(
    "/health",
    response_model=HealthOut,
    responses={503: {"model": HealthOut, "description": "Database or Redis unreachable"}},
)
def health(services: ServicesDep):
    """``{"status": "ok", "workers": n, "queued": n}`` and which executor and database state.
    503 (same body, status "degraded") when the database or Redis cannot be reached."""
    database = "ok" if database_reachable(services.engine) else "unreachable"
    workers, queued, executor_ok = services.executor_status()
    body = HealthOut(
        status="ok" if database == "ok" and executor_ok else "degraded",
        workers=workers,
        queued=queued,
        executor=services.executor_kind,
        database=database,
        coordinator=services.loop is not None,
    )
    if body.status != "ok":
        return JSONResponse(body.model_dump(), status_code=503)
    return body
