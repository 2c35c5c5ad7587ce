"""``softevo plan PRESET_OR_SPEC``: what an experiment grid costs before it runs
(``service.plan.model``): wall time, core- or GPU-hours, database size, utilisation.

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
    takes it (``service.plan.spec``); UserError for anything else."""
    from softevo.evolution.treatments import PRESETS, preset_grid
    from softevo.service.plan.spec import spec_treatments

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
        typer.Option("--executor", help="local (the default): softevo run's and experiment's process pool "
                     "on one machine; rq: a cluster (softevo serve, Redis workers)"),
    ] = "local",
    as_json: JsonOption = False,
) -> None:
    """What a grid costs: wall time, core- or GPU-hours, database size and utilisation."""
    from softevo.service.plan import model as planner
    from softevo.worker.physics import MEASURED
    from softevo.worker.physics import measure as measure_rates

    planner.check_devices(cores, gpus)
    planner.check_coordinators(coordinators)
    if executor not in planner.EXECUTOR_KINDS:
        raise UserError(f"--executor must be one of {', '.join(planner.EXECUTOR_KINDS)} (got {executor!r})")
    treatments = treatments_of(preset_or_spec, scale)
    cost = MEASURED
    if measure:
        cost = measure_rates(planner.scenes_for_measure(treatments), repeats=1)
    def planned(n: int):
        return planner.plan(treatments, cores=cores, gpus=gpus, cost=cost, coordinators=n, executor=executor)

    result = planned(coordinators)
    more = None  # coordinator-bound: the plan with as many coordinators as keep each under 80%
    if coordinator_bound(result):
        more = planned(result.coordinators_needed())
    if as_json:
        typer.echo(json.dumps(result.to_json(), indent=2))
        return
    typer.echo(plan_text(result, more))


def coordinator_bound(result) -> bool:
    """Whether the coordinators limit the plan: busy over 80% of the time, and more of them
    would keep each under it."""
    from softevo.service.plan.model import COORDINATOR_TARGET

    busy = result.coordinator_utilisation > COORDINATOR_TARGET
    return busy and result.coordinators_needed() > result.coordinators


def plan_text(result, more=None) -> str:
    """The plan as a table per treatment and the totals, in units a person reads (``duration``,
    ``amount``). Each treatment's core- (GPU-) time is its share of the booked total, in
    proportion to its evaluations' own seconds (voxel-steps on GPUs), so that the column adds
    up to the total; ``more``: the plan with as many coordinators as ``result`` needs, when
    it is coordinator-bound."""
    device = "core" if result.cores else "GPU"
    booked = result.booked_hours * 3600
    scale, unit = time_unit(booked)
    size, size_unit = byte_unit(result.database_bytes)
    weights = [t.core_seconds if result.cores else t.voxel_steps for t in result.treatments]
    column = f"{device}-{unit}"
    rows = [f"{'treatment':<24} {'runs':>5} {'gens':>6} {'evaluations':>12} {'s/eval mean (p90)':>20} "
            f"{column:>9} {'DB ' + size_unit:>7}"]
    for t, weight in zip(result.treatments, weights, strict=True):
        spread = " ".join(f"{v['mean']:.3g} ({v['p90']:.3g})" for v in t.seconds_per_evaluation.values())
        share = booked * weight / sum(weights) if sum(weights) else 0.0
        rows.append(f"{t.name:<24} {t.runs:>5} {t.generations:>6} {t.evaluations:>12,} {spread:>20} "
                    f"{share / scale:>9.3g} {t.database_bytes / size:>7.3g}")
    runs = sum(t.runs for t in result.treatments)
    rows.append(f"{'total':<24} {runs:>5} {'':>6} {result.evaluations:>12,} "
                f"{'':>20} {booked / scale:>9.3g} {result.database_bytes / size:>7.3g}")
    devices = f"{result.cores} cores" if result.cores else f"{result.gpus} GPUs"
    how = f"{result.executor} executor, {result.dispatch} dispatch" if result.cores else "rounds"
    rows += [
        "",
        f"on {devices} ({how}): wall {duration(result.wall_seconds)}, utilisation {result.utilisation:.0%}",
        f"booked {amount(booked, device)} (wall x {devices}) = "
        f"{amount(result.busy_hours * 3600, device, booked)} evaluating + "
        f"{amount(result.idle_hours * 3600, device, booked)} idle (waiting for the coordinator, "
        "a round's slowest job, the start)",
    ]
    if result.cores:
        rows.append(useful_text(result))
    rows.append(f"{result.evaluations:,} evaluations, {result.voxel_steps:.3g} voxel-steps, "
                f"database {size_text(result.database_bytes)}")
    rows.append(coordinator_text(result, more))
    if result.gpus:
        rows.append(f"GPU rate {result.cost['gpu_rate']:.2g} voxel-steps/s: {result.cost['gpu_rate_source']}")
        rows.append(gpu_text(result, sum(t.core_seconds for t in result.treatments) / 3600))
    rows += [f"assumes: {note}" for note in result.assumptions]
    return "\n".join(rows)


def useful_text(result) -> str:
    """Where more cores stop helping (``useful_cores``) and why: the floor the runs' chains of
    generations set."""
    generations = {t.generations for t in result.treatments}
    most = max(generations)
    chain = (f"each run's {most:,} generations go one after another" if len(generations) == 1
             else f"a run's generations go one after another ({result.longest_run!r} runs {most:,})")
    waits = ("its round's slowest evaluation (every run's generation together)"
             if result.dispatch == "rounds" else "its slowest evaluation")
    start = f"; the start adds {duration(result.startup_seconds)}" if result.startup_seconds else ""
    if coordinator_bound(result):
        chain = f"the coordinator{'s' if result.coordinators > 1 else ''} cannot keep up (below)"
        return (f"past about {result.useful_cores:,} cores the wall stops shrinking (they come within 10% "
                f"of the {duration(result.floor_wall_seconds)} that unlimited cores give): {chain}{start}")
    return (f"past about {result.useful_cores:,} cores the wall stops shrinking (they come within 10% of "
            f"the {duration(result.floor_wall_seconds)} that unlimited cores give): {chain}, each waiting "
            f"for {waits} and for the coordinator{start}")


def time_unit(seconds: float) -> tuple[float, str]:
    """(seconds in it, name) of the unit ``seconds`` reads best in: s, min or h."""
    if seconds < 120:
        return 1.0, "s"
    return (60.0, "min") if seconds < 2 * 3600 else (3600.0, "h")


def duration(seconds: float) -> str:
    """``seconds`` in seconds, minutes or hours (days beside it past 3 days)."""
    scale, unit = time_unit(seconds)
    words = {"s": "seconds", "min": "minutes", "h": "hours"}[unit]
    text = f"{_figure(seconds / scale)} {words}"
    if seconds >= 3 * 86400:
        text += f" ({_figure(seconds / 86400)} days)"
    return text


def amount(seconds: float, device: str = "core", like: float | None = None) -> str:
    """Device-time ``seconds`` as core- or GPU-seconds, -minutes or -hours (those ``like``
    reads best in, when given: figures to add up in one unit)."""
    scale, unit = time_unit(seconds if like is None else like)
    words = {"s": "seconds", "min": "minutes", "h": "hours"}[unit]
    return f"{_figure(seconds / scale)} {device}-{words}"


def byte_unit(size: float) -> tuple[float, str]:
    """(bytes in it, name) of the unit ``size`` reads best in: kB, MB or GB."""
    for scale, unit in ((GB, "GB"), (1e6, "MB")):
        if size >= scale:
            return scale, unit
    return 1e3, "kB"


def size_text(size: float) -> str:
    scale, unit = byte_unit(size)
    return f"{_figure(size / scale)} {unit}"


def _figure(value: float) -> str:
    """Three significant figures, with thousands separated and no exponent."""
    return f"{float(f'{value:.3g}'):,.0f}" if abs(value) >= 100 else f"{value:.3g}"


def coordinator_text(result, more=None) -> str:
    """How busy the coordinators are, and when they limit the plan what more of them give."""
    busy = f"{result.coordinators} coordinator(s) busy {result.coordinator_utilisation:.0%} of the time"
    if more is None:
        return f"{busy}; {result.coordinators_needed()} keep(s) each under 80%"
    return (f"coordinator-bound ({busy}): --coordinators {more.coordinators} gives about "
            f"{duration(more.wall_seconds)} (from {duration(result.wall_seconds)})")


def gpu_text(result, evaluation_hours: float) -> str:
    """Why the GPUs take as long as they do, against CPU cores: their voxel-steps per second
    as a number of this machine's cores, and what a round waits for."""
    rate = result.cost["gpu_rate"] * result.gpus
    per_core = result.voxel_steps / (evaluation_hours * 3600) if evaluation_hours else 0.0
    cores = rate / per_core if per_core else 0.0
    coordinator = min(1.0, result.coordinator_seconds / result.wall_seconds) if result.wall_seconds else 0.0
    return (f"why: {result.gpus} GPUs step {rate:.2g} voxel-steps/s in all, as many as about {cores:,.0f} "
            f"CPU cores at {per_core:.2g} per core; and each round (a generation of every run) waits for "
            f"its longest robot (a batch steps in lock-step: GPUs busy {result.utilisation:.0%}) and for "
            f"the coordinator ({coordinator:.0%} of the wall), so more cores than that finish sooner")


def register(app: typer.Typer) -> None:
    """Add ``plan`` to ``app``."""
    app.command("plan")(plan)
