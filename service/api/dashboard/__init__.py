"""The web dashboard: experiments, runs and individuals in a browser, with a 3D
replay of an individual's evaluated motion.

``dashboard_router()`` gives the routes the API app includes (``service.api.app``), so
``softevo serve`` (distributed service) and ``softevo dashboard`` (embedded database, no
coordinator) serve the same pages:

    /dashboard/                          experiments and their runs, live status
    /dashboard/experiments/{id}          treatments side by side: fitness, fronts, descriptors,
                                         statistics, downloads, every run
    /dashboard/runs/{id}                 fitness curves, Pareto front by generation
    /dashboard/runs/{id}/tree            the phylogeny as a tree over generations (``tree``)
    /dashboard/individuals/{id}          genome, objectives, descriptors, lineage, 3D replay
    /dashboard/static/...                CSS, JS modules, vendored three.js, plotly.js
    /dashboard/api/individuals/{id}/body lattice, materials and actuation phases (JSON)

The pages are static HTML shells; plain JS modules (no build step) fill them from the REST
API (``/experiments``, ``/runs/...``, ``/individuals/...``). Motion comes from
``GET /individuals/{id}/frames`` as float32 binary (``service.api.frames``). Nothing is
fetched from outside the server. None of these routes is in the OpenAPI schema.
"""

from __future__ import annotations

from fastapi import APIRouter

from softevo.service.api.dashboard import assets, body, pages, tree

PREFIX = "/dashboard"


def dashboard_router() -> APIRouter:
    """The dashboard's pages, assets and helper endpoint under ``/dashboard``."""

    router = APIRouter(prefix=PREFIX, include_in_schema=False)
    for module in (assets, body, pages, tree):
        router.include_router(module.router)
    return router
