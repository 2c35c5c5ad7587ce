"""GET /worlds: the world registry (``sim.worlds``), what the dashboard draws worlds with."""

from __future__ import annotations

from fastapi import APIRouter

from softevo.evolution import environments
from softevo.service.api.schemas import WorldOut

router = APIRouter(tags=["worlds"])


@router.get("/worlds", response_model=list[WorldOut])
def world_list() -> list[WorldOut]:
    """Every registered world in registration order: its physics (gravity, floor, drag, how
    distance is measured, settling time), its colours and report label, and whether it is
    offered for evolution. The dashboard's pages colour worlds from this list."""
    return [WorldOut(**world.to_json()) for world in environments.all_worlds()]
