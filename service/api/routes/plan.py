"""/plan: what an experiment would cost (``service.plan.model``), before it is submitted.

It stores nothing, so it needs no token; its work is bounded: the planner's fixed sample
sizes, at most ``MAX_PLAN_TREATMENTS`` treatments, ``MAX_PLAN_POPULATION`` individuals over
their populations and ``MAX_PLAN_GENOMES`` per round over the runs; no re-measuring of rates
(``softevo plan --measure`` does that).
"""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter
from fastapi.concurrency import run_in_threadpool

from softevo.errors import UserError
from softevo.service.api.deps import COMMON, ServicesDep
from softevo.service.api.requests import request_treatments
from softevo.service.api.schemas import ErrorOut, PlanRequest
from softevo.service.plan.model import check_devices, plan

router = APIRouter(prefix="/plan", tags=["plan"], responses=COMMON)
MAX_PLAN_TREATMENTS = 24  # each is probed and costed (the paper grid has 12)
MAX_PLAN_POPULATION = 1_000  # individuals over the treatments' populations (probed)
MAX_PLAN_GENOMES = 10_000  # individuals per round over every run (simulated dispatch)


def bounded(treatments: list) -> list:
    """``treatments``, or UserError (422) when they are more than /plan plans."""
    population = sum(t.population for t in treatments)
    genomes = sum(t.population * t.repetitions for t in treatments)
    if (len(treatments) > MAX_PLAN_TREATMENTS or population > MAX_PLAN_POPULATION
            or genomes > MAX_PLAN_GENOMES):
        raise UserError(
            f"too large to plan here ({len(treatments)} treatments, {population} individuals over "
            f"their populations, {genomes} per round over the runs; at most {MAX_PLAN_TREATMENTS}, "
            f"{MAX_PLAN_POPULATION} and {MAX_PLAN_GENOMES}): use softevo plan"
        )
    return treatments


@router.post(
    "",
    response_model=dict[str, Any],
    responses={
        400: {"model": ErrorOut, "description": "The body is not JSON"},
        413: {"model": ErrorOut, "description": "The body is larger than SOFTEVO_MAX_BODY_BYTES"},
    },
)
async def plan_experiment(
    body: PlanRequest, services: ServicesDep
) -> dict[str, Any]:
    """The plan of an experiment body (as ``POST /experiments`` takes it) on ``cores`` CPU
    workers or ``gpus`` GPUs: ``wall_seconds, core_hours, gpu_hours, database_bytes,
    utilisation, evaluations, voxel_steps``, the coordinators' share busy, ``useful_cores``
    and per-treatment lines; through ``executor``, by default this server's own. 422 for
    neither or both."""
    check_devices(body.cores, body.gpus)
    treatments = bounded(request_treatments(body))
    result = await run_in_threadpool(
        plan,
        treatments,
        cores=body.cores,
        gpus=body.gpus,
        coordinators=body.coordinators,
        executor=body.executor or ("rq" if services.settings.redis_url else "local"),
    )
    return result.to_json()
