"""``softevo plan PRESET_OR_SPEC``: what an experiment grid costs before it runs
(``service.plan``): wall time, core- or GPU-hours, database size, utilisation.

PRESET_OR_SPEC is a preset (``paper``, ``gradual``) at ``--scale``, or a JSON file holding
what ``POST /experiments`` takes (``{"name", "treatments": [...]}`` or ``{"preset",
"scale"}``).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from softevo.errors import UserError
from softevo.service.cli.options import JsonOption

GB = 1e9


def treatments_of(preset_or_spec: str, scale: str):
    """The treatments of a preset at ``scale``, or of a spec file as ``POST /experiments``
    takes it (validated by the API's own schema); UserError for anything else."""
    from softevo.service.treatments import PRESETS, preset_grid

    if preset_or_spec in PRESETS:
        return preset_grid(preset_or_spec, scale)
    path = Path(preset_or_spec)
    if not path.is_file():
        raise UserError(f"{preset_or_spec!r} is neither a preset ({' or '.join(PRESETS)}) nor a spec file")
    try:
        body = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise UserError(f"{path}: not a JSON spec ({exc})") from None
    return spec_treatments(body, where=str(path))


def spec_treatments(body, where: str = "spec"):
    """The treatments of an experiment body (``service.api.schemas.ExperimentRequest``)."""
    from pydantic import TypeAdapter, ValidationError

    from softevo.service.api.requests import request_treatments
    from softevo.service.api.schemas import ExperimentRequest, problem_line, request_problems

    try:
        request = TypeAdapter(ExperimentRequest).validate_python(body, strict=False)
    except ValidationError as exc:
        raise UserError(f"{where}: {problem_line(request_problems(exc.errors()))}") from None
    try:
        return request_treatments(request)
    except UserError as exc:
        raise UserError(f"{where}: {exc}") from None


def plan(
    preset_or_spec: Annotated[
        str, typer.Argument(metavar="PRESET_OR_SPEC", help="paper, gradual or a JSON spec file")
    ],
    scale: Annotated[str, typer.Option("--scale", help="a preset's scale")] = "tiny",
    cores: Annotated[int | None, typer.Option("--cores", help="CPU workers (one core each)")] = None,
    gpus: Annotated[int | None, typer.Option("--gpus", help="GPUs (rate: an estimate, not measured)")] = None,
    measure: Annotated[
        bool, typer.Option("--measure", help="measure the per-core rates here first (~30 s)")
    ] = False,
    coordinators: Annotated[
        int, typer.Option("--coordinators", help="coordinator processes sharing the runs")
    ] = 1,
    executor: Annotated[
        str,
        typer.Option("--executor", help="rq: a cluster (softevo serve, Redis workers); local: softevo run's "
                     "process pool on one machine"),
    ] = "rq",
    as_json: JsonOption = False,
) -> None:
    """What a grid costs: wall time, core- or GPU-hours, database size and utilisation."""
    from softevo.service import plan as planner
    from softevo.sim.cost import MEASURED
    from softevo.sim.cost import measure as measure_rates

    planner.check_devices(cores, gpus)
    planner.check_coordinators(coordinators)
    if executor not in planner.EXECUTORS:
        raise UserError(f"--executor must be one of {', '.join(planner.EXECUTORS)} (got {executor!r})")
    treatments = treatments_of(preset_or_spec, scale)
    cost = MEASURED
    if measure:
        cost = measure_rates(planner.scenes_for_measure(treatments), repeats=1)
    result = planner.plan(
        treatments, cores=cores, gpus=gpus, cost=cost, coordinators=coordinators, executor=executor
    )
    typer.echo(json.dumps(result.to_json(), indent=2) if as_json else plan_text(result))


def plan_text(result) -> str:
    """The plan as a table per treatment and the totals, with units."""
    rows = [f"{'treatment':<24} {'runs':>5} {'gens':>6} {'evaluations':>12} {'s/eval mean (p90)':>20} "
            f"{'core-h':>9} {'DB GB':>7}"]
    for t in result.treatments:
        spread = " ".join(f"{v['mean']:.3g} ({v['p90']:.3g})" for v in t.seconds_per_evaluation.values())
        rows.append(f"{t.name:<24} {t.runs:>5} {t.generations:>6} {t.evaluations:>12,} {spread:>20} "
                    f"{t.core_seconds / 3600:>9.3g} {t.database_bytes / GB:>7.3g}")
    device = f"{result.cores} cores" if result.cores else f"{result.gpus} GPUs"
    hours = f"{result.core_hours:,.4g} core-hours" if result.cores else f"{result.gpu_hours:,.4g} GPU-hours"
    rows += [
        "",
        f"on {device} ({result.dispatch} dispatch): wall {result.wall_hours:,.4g} hours, {hours}, "
        f"utilisation {result.utilisation:.0%}",
        f"{result.evaluations:,} evaluations, {result.voxel_steps:.3g} voxel-steps, "
        f"database {result.database_bytes / GB:,.3g} GB",
        f"{result.coordinators} coordinator(s) busy {result.coordinator_utilisation:.0%} of the time; "
        f"{result.coordinators_needed()} keep(s) each under 80%",
    ]
    if result.gpus:
        rows.append(f"GPU rate {result.cost['gpu_rate']:.2g} voxel-steps/s: {result.cost['gpu_rate_source']}")
    rows += [f"assumes: {note}" for note in result.assumptions]
    return "\n".join(rows)


def register(app: typer.Typer) -> None:
    """Add ``plan`` to ``app``."""
    app.command("plan")(plan)
