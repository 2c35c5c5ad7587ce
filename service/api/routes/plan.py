"""/plan: what an experiment would cost (``service.plan``), before it is submitted.

It stores nothing, so it needs no token; its work is bounded: the planner's fixed sample
sizes, at most ``MAX_PLAN_RUNS`` runs and ``MAX_PLAN_POPULATION`` individuals over the
treatments' populations, no re-measuring of rates (``softevo plan --measure`` does that).
"""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter
from fastapi.concurrency import run_in_threadpool

from softevo.errors import UserError
from softevo.service.api.deps import COMMON
from softevo.service.api.routes.experiments import request_treatments
from softevo.service.api.schemas import PlanRequest
from softevo.service.plan import check_devices, plan

router = APIRouter(prefix="/plan", tags=["plan"], responses=COMMON)
MAX_PLAN_RUNS = 5_000
MAX_PLAN_POPULATION = 20_000


def bounded(treatments: list) -> list:
    """``treatments``, or UserError (422) when they are more than /plan plans."""
    runs = sum(t.repetitions for t in treatments)
    population = sum(t.population for t in treatments)
    if runs > MAX_PLAN_RUNS or population > MAX_PLAN_POPULATION:
        raise UserError(f"too large to plan here: {runs} runs (at most {MAX_PLAN_RUNS}) and "
                        f"{population} individuals per generation (at most {MAX_PLAN_POPULATION}); "
                        "use softevo plan")
    return treatments


@router.post("", response_model=dict[str, Any])
async def plan_experiment(body: PlanRequest) -> dict[str, Any]:
    """The plan of an experiment body (as ``POST /experiments`` takes it) on ``cores`` CPU
    workers or ``gpus`` GPUs: ``wall_seconds, core_hours, gpu_hours, database_bytes,
    utilisation, evaluations, voxel_steps`` and per-treatment lines. 422 for neither or both."""
    check_devices(body.cores, body.gpus)
    treatments = bounded(request_treatments(body))
    result = await run_in_threadpool(plan, treatments, cores=body.cores, gpus=body.gpus)
    return result.to_json()
