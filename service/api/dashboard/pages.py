"""The dashboard's HTML pages: static shells from ``templates/`` that JS modules fill from
the REST API. A page for an unknown run or individual is a 404 page.

Every URL in a page starts with the app's root path (``request.scope["root_path"]``), so the
dashboard also works behind a reverse proxy that serves the API under a prefix.
"""

from __future__ import annotations

import html
import json
from functools import cache
from pathlib import Path as FilePath
from string import Template

from fastapi import APIRouter, Request
from fastapi.responses import HTMLResponse

from softevo.evolution import environments, traits
from softevo.service.api.deps import ConnectionDep
from softevo.service.api.headers import policy
from softevo.service.api.params import ExperimentId, IndividualId, RunId
from softevo.service.storage import experiments as db_experiments
from softevo.service.storage import individuals as db_individuals
from softevo.service.storage import runs as db_runs

TEMPLATES = FilePath(__file__).parent / "templates"

router = APIRouter()



@cache
def template(name: str) -> Template:
    return Template((TEMPLATES / name).read_text(encoding="utf-8"))


def render(request: Request, page: str, title: str, status_code: int = 200, **values) -> HTMLResponse:
    """``templates/<page>`` inside ``layout.html``; ``values`` fill the page's ``$names``
    (HTML-escaped), ``$root``, ``$static`` and ``$worlds`` (the world registry as JSON, what
    ``GET /worlds`` answers; ``static/js/worlds.js`` reads it) and ``$traits`` (every trait's
    label, ``evolution.traits.labels()``) are filled everywhere."""
    root = html.escape(request.scope.get("root_path", "").rstrip("/"))
    registry = json.dumps([world.to_json() for world in environments.all_worlds()])
    labels = json.dumps(traits.labels())
    common = {"root": root, "static": f"{root}/dashboard/static", "worlds": html.escape(registry),
              "traits": html.escape(labels)}
    escaped = {key: html.escape(str(value)) for key, value in values.items()}
    content = template(page).substitute(common, **escaped)
    body = template("layout.html").substitute(
        common, title=html.escape(title), content=content, page=page.removesuffix(".html")
    )
    return HTMLResponse(body, status_code=status_code, headers={"Content-Security-Policy": page_policy(body)})


def page_policy(body: str) -> str:
    """The CSP of a dashboard page: scripts from this origin and its import map by hash;
    ``'unsafe-eval'`` because plotly.js's full bundle builds functions at run time."""
    return policy(body, scripts="'self' 'unsafe-eval'")


def not_found(request: Request, message: str) -> HTMLResponse:
    return render(request, "missing.html", "Not found", status_code=404, message=message)


@router.get("/", response_class=HTMLResponse)
def index(request: Request) -> HTMLResponse:
    """Experiments and their runs, with live status."""
    return render(request, "index.html", "Experiments")


@router.get("/experiments/{experiment_id}", response_class=HTMLResponse)
def experiment_page(request: Request, experiment_id: ExperimentId, conn: ConnectionDep) -> HTMLResponse:
    """An experiment's treatments side by side: fitness curves, aggregated Pareto fronts,
    descriptors, the statistics table, downloads and every run."""
    if not db_experiments.experiment_exists(conn, experiment_id):
        return not_found(request, f"There is no experiment {experiment_id}.")
    return render(request, "experiment.html", f"Experiment {experiment_id}", experiment_id=experiment_id)


@router.get("/runs/{run_id}", response_class=HTMLResponse)
def run_page(request: Request, run_id: RunId, conn: ConnectionDep) -> HTMLResponse:
    """A run: fitness curves and its Pareto front by generation."""
    if db_runs.run_status(conn, run_id) is None:
        return not_found(request, f"There is no run {run_id}.")
    return render(request, "run.html", f"Run {run_id}", run_id=run_id)


@router.get("/individuals/{individual_id}", response_class=HTMLResponse)
def individual_page(request: Request, individual_id: IndividualId, conn: ConnectionDep) -> HTMLResponse:
    """An individual: genome summary, objectives, descriptors, lineage and 3D replay."""
    run_id = db_individuals.individual_run_id(conn, individual_id)
    if run_id is None:
        return not_found(request, f"There is no individual {individual_id}.")
    return render(
        request, "individual.html", f"Individual {individual_id}", individual_id=individual_id, run_id=run_id
    )
