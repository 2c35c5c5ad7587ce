"""``softevo run | experiment | status | resume | export | lineage | best`` (docs/spec.md section 7).

Everything runs embedded: a SQLite file (``--db`` or ``SOFTEVO_DB``, default
``sqlite:///softevo.db``) and a local process pool. Runs and experiments are named by
``RUN_OR_EXPERIMENT``: ``5``, ``r5`` or ``run-5`` for run 5; ``e2`` or ``exp-2`` for
experiment 2; ``latest`` for the newest experiment; or an experiment's name. A command on
one run (``best``) takes an experiment of one run too; INDIVIDUAL (``lineage``) is an
individual id or a run, for its best individual (``service.storage.runs``: the one resolver).

Each command imports what it uses inside its function: ``softevo --help`` and every other
command start without loading SQLAlchemy, pandas, numba or rich.
"""

from __future__ import annotations

import inspect
import json
import os
from typing import Annotated, Any

import typer

from softevo.errors import UserError
from softevo.evolution import options
from softevo.evolution.treatments import SCALES
from softevo.service.cli.options import (
    INDIVIDUAL_HELP,
    DbOption,
    JsonOption,
    QuietOption,
    RunArgument,
    WorkersOption,
    say_bare_number,
)

EVOLVED_STIFFNESS_PLACEHOLDER_MPA = 0.1  # the treatment's scalar when the field is evolved


def option_help(option: options.Option) -> str:
    """An option's help on the command line: its help text, unit and choices (read now)."""
    unit = f" ({option.unit})" if option.unit and not option.sequence else ""
    choices = f" (one of {', '.join(option.choices())})" if option.choices is not None else ""
    spelling = " (comma-separated)" if option.sequence else ""
    return f"{option.help}{unit}{spelling}{choices}"


def option_parameter(option: options.Option) -> inspect.Parameter:
    """The ``softevo run`` parameter of a declared treatment option: a flag for a boolean, a
    comma-separated text for a sequence (``Option.parse``), else the value's type (None
    where the option is optional or required: a missing required one is reported by
    ``run``)."""
    if option.type is bool and not option.sequence:
        flag = option.flag if option.default is not True else f"{option.flag}/--no-{option.flag[2:]}"
        kind, default = bool, bool(option.default)
    elif option.sequence:
        flag, kind, default = option.flag, str, option.format(option.default)
    else:
        flag, kind = option.flag, option.type | None
        default = None if option.required else option.default
    annotation = Annotated[kind, typer.Option(flag, help=option_help(option))]
    return inspect.Parameter(option.name, inspect.Parameter.KEYWORD_ONLY, default=default,
                             annotation=annotation)


def _workers(workers: int | None) -> int:
    if workers is not None and workers < 0:
        raise UserError(f"--workers must be >= 0 (got {workers})")
    if workers is None:
        return os.cpu_count() or 1
    return workers


def _execute(engine, run_ids: list[int], workers: int | None, quiet: bool) -> None:
    """Advance ``run_ids`` to their end with a progress bar; print a summary line per run."""
    from softevo.service.cli.progress import progress_bar
    from softevo.service.runs.coordinator import Coordinator, unfinished_runs
    from softevo.service.runs.executors import make_executor

    runs = unfinished_runs(engine, run_ids)
    if not runs:
        typer.echo("nothing to do: every run is finished")
        return
    total, done = _generation_counts(engine, runs)
    executor = make_executor(_workers(workers))
    try:
        with progress_bar(total, done, enabled=not quiet) as reporter:
            Coordinator(engine, executor, on_generation=reporter).run(runs)
    except KeyboardInterrupt:
        typer.echo("interrupted: every finished generation is stored; continue with softevo resume", err=True)
        raise typer.Exit(130) from None
    finally:
        executor.close()
    failed = _print_status(engine, run_ids)
    if failed:
        raise typer.Exit(1)  # ``softevo run ... && softevo report ...`` stops at a failed run


def _generation_counts(engine, run_ids: list[int]) -> tuple[int, int]:
    from softevo.service.storage.runs import run_row

    with engine.connect() as conn:
        rows = [run_row(conn, run_id) for run_id in run_ids]
    return sum(r["generations"] for r in rows), sum(r["generation"] + 1 for r in rows)


class RunCommand:
    """Evolve one treatment (its repetitions' runs) and store every individual. The defaults
    keep the quick start's meaning (AFPO, voxelyze-2); ``softevo experiment`` runs the paper's
    choices."""

    __name__ = __qualname__ = "run"
    __module__ = __name__

    @property
    def __signature__(self) -> inspect.Signature:
        """The command's parameters: one per declared treatment option (``evolution.options``),
        read each time typer builds the command, then the run's own."""
        own = [
            inspect.Parameter("ctx", inspect.Parameter.KEYWORD_ONLY, annotation=typer.Context),
            *(option_parameter(option) for option in options.declared()),
            inspect.Parameter("name", inspect.Parameter.KEYWORD_ONLY, default=None, annotation=Annotated[
                str | None, typer.Option("--name", help="the experiment's name (default: the treatment's, "
                                         "e.g. 'land S=1MPa')")]),
        ]
        shared = [inspect.Parameter(name, inspect.Parameter.KEYWORD_ONLY, default=default, annotation=kind)
                  for name, kind, default in (("db", DbOption, None), ("workers", WorkersOption, None),
                                              ("quiet", QuietOption, False))]
        return inspect.Signature([*own, *shared])

    @property
    def __annotations__(self) -> dict[str, Any]:
        return {p.name: p.annotation for p in self.__signature__.parameters.values()}

    def __call__(self, ctx: typer.Context, name: str | None = None, db: str | None = None,
                 workers: int | None = None, quiet: bool = False, **given: Any) -> None:
        from softevo.evolution.treatments import Treatment
        from softevo.service.runs.limits import check_treatment
        from softevo.service.runs.submit import create
        from softevo.service.storage import open_database

        declared = options.declared()
        values = {o.name: o.parse(given[o.name]) if o.sequence else given[o.name] for o in declared}
        if values.get("stiffness_mpa") is None and values.get("evolve_stiffness"):
            values["stiffness_mpa"] = EVOLVED_STIFFNESS_PLACEHOLDER_MPA
        for option in declared:
            if option.required and values[option.name] is None:
                alone = " (or --evolve-stiffness)" if option.name == "stiffness_mpa" else ""
                raise UserError(f"missing option '{option.flag}'{alone}")
        treatment = Treatment(**values)
        check_treatment(treatment)  # the REST API's bounds, before anything is stored
        if name is not None and not name.strip():
            raise UserError("--name must not be empty")
        engine = open_database(db)
        experiment_id, run_ids = create(engine, name or treatment.name, [treatment])
        runs = f"run {run_ids[0]}" if len(run_ids) == 1 else f"runs {run_ids[0]}..{run_ids[-1]}"
        typer.echo(f"experiment {experiment_id} (e{experiment_id}): {runs}", err=True)
        _execute(engine, run_ids, workers, quiet)


run = RunCommand()


def _paper_help(name: str) -> str:
    option = options.option(name)
    return f"{option_help(option)} (default {option.paper})"


def experiment(
    preset: Annotated[
        str,
        typer.Argument(
            help="paper: the paper's grid (docs/spec.md section 5); gradual: its two "
            "transitions, abrupt and gradual"
        ),
    ],
    scale: Annotated[str, typer.Option("--scale", help=" | ".join(SCALES))] = "tiny",
    repetitions: Annotated[int | None, typer.Option("--repetitions")] = None,
    seed: Annotated[int, typer.Option("--seed")] = 0,
    algorithm: Annotated[str | None, typer.Option("--algorithm", help=_paper_help("algorithm"))] = None,
    model: Annotated[str | None, typer.Option("--model", help=_paper_help("model"))] = None,
    control_mapping: Annotated[
        str | None, typer.Option("--control-mapping", help=_paper_help("control_mapping"))
    ] = None,
    treatments: Annotated[
        str | None,
        typer.Option("--treatments", help="only these treatments, comma-separated, e.g. "
                     "'land S3,water S3' (their seeds as in the whole preset)"),
    ] = None,
    name: Annotated[
        str | None, typer.Option("--name", help="the experiment's name (default PRESET-SCALE)")
    ] = None,
    db: DbOption = None,
    workers: WorkersOption = None,
    quiet: QuietOption = False,
) -> None:
    """Run a preset experiment: every treatment and repetition (or those of --treatments),
    with the paper's algorithm (plain Pareto), model (voxcad-land-water) and encoding unless
    --algorithm / --model."""
    from softevo.evolution.treatments import preset_grid, select_treatments
    from softevo.service.runs.submit import create_paper
    from softevo.service.storage import open_database

    if repetitions is not None and repetitions < 1:
        raise UserError(f"--repetitions must be >= 1 (got {repetitions})")
    choices = {"algorithm": algorithm, "model": model, "control_mapping": control_mapping}
    only = None if treatments is None else treatments.split(",")
    grid = preset_grid(preset, scale, **choices)  # validates everything before touching the database
    if only is not None:
        select_treatments(grid, only)
    if name is not None and not name.strip():
        raise UserError("--name must not be empty")
    engine = open_database(db)
    experiment_id, run_ids = create_paper(engine, scale, repetitions, seed, preset=preset, only=only,
                                          name=name, **choices)
    typer.echo(f"experiment {experiment_id} (e{experiment_id}): runs {run_ids[0]}..{run_ids[-1]}", err=True)
    _execute(engine, run_ids, workers, quiet)


def _print_status(engine, run_ids: list[int]) -> list[int]:
    """Print the runs' table, and below it one line per failed run saying why (stderr);
    return the failed runs' ids."""
    from rich import box
    from rich.console import Console
    from rich.table import Table

    from softevo.service.storage.status import run_summaries

    caption = "best: of the last generation; per world: of any generation in it"
    summaries = run_summaries(engine, run_ids)
    table = Table("run", "exp", "treatment", "rep", "seed", "status", "gens stored", "world", "best",
                  box=box.SIMPLE_HEAD, show_edge=False, collapse_padding=True, caption=caption)  # fmt: skip
    table.add_column("per world", no_wrap=True)
    for r in summaries:
        per_world = "\n".join(f"{world} {best:.3f}" for world, best in r["best_by_world"].items())
        table.add_row(
            str(r["run_id"]),
            f"e{r['experiment_id']}",
            r["treatment"],
            str(r["repetition"]),
            str(r["seed"]),
            r["status"],
            f"{r['generation'] + 1}/{r['generations']}",
            r["environment"] or "-",
            _fmt(r["best_distance"]),
            per_world or "-",
        )
    Console().print(table)
    failed = [r for r in summaries if r["status"] == "failed"]
    for r in failed:
        typer.echo(f"run {r['run_id']} failed: {r['error'] or 'no reason stored'}", err=True)
    return [r["run_id"] for r in failed]


def status(
    reference: Annotated[str | None, typer.Argument(metavar="[RUN_OR_EXPERIMENT]")] = None,
    db: DbOption = None,
) -> None:
    """Show runs: status, generation, world and best distance of the last generation, and
    the best distance reached in each world."""
    from softevo.service.storage import open_database
    from softevo.service.storage.runs import resolve_runs

    engine = open_database(db, create=False)
    say_bare_number(reference, "run")
    with engine.connect() as conn:
        run_ids = resolve_runs(conn, reference)
    if not run_ids:
        typer.echo("no runs yet")
        return
    _print_status(engine, run_ids)


def resume(
    reference: Annotated[str | None, typer.Argument(metavar="[RUN_OR_EXPERIMENT]")] = None,
    db: DbOption = None,
    workers: WorkersOption = None,
    quiet: QuietOption = False,
) -> None:
    """Continue unfinished runs from their last stored generation.

    Without an argument: every pending or running run. Runs named explicitly are continued
    even if they were cancelled or failed.
    """
    from softevo.service.storage import open_database
    from softevo.service.storage.runs import reopen_runs, resolve_runs

    engine = open_database(db, create=False)
    say_bare_number(reference, "run")
    with engine.begin() as conn:
        run_ids = resolve_runs(conn, reference)
        if reference is not None:
            reopen_runs(conn, run_ids)
    _execute(engine, run_ids, workers, quiet)


def export(
    reference: Annotated[str, typer.Argument(metavar="RUN_OR_EXPERIMENT")],
    out: Annotated[str, typer.Option("--out", help="output directory")],
    fmt: Annotated[str, typer.Option("--format", help="csv | parquet")] = "csv",
    db: DbOption = None,
) -> None:
    """Write runs, individuals (one row per evaluation) and populations files."""
    from softevo.service.storage import open_database
    from softevo.service.storage.export import export_runs
    from softevo.service.storage.runs import resolve_runs

    engine = open_database(db, create=False)
    say_bare_number(reference, "run")
    with engine.connect() as conn:
        run_ids = resolve_runs(conn, reference)
    for path in export_runs(engine, run_ids, out, fmt):
        typer.echo(str(path))


def one_individual(db: str | None, reference: str):
    """(engine, individual id) of the database ``db`` and the individual ``reference`` names
    (``service.storage.runs.resolve_individual``)."""
    from softevo.service.storage import open_database
    from softevo.service.storage.runs import resolve_individual

    engine = open_database(db, create=False)
    say_bare_number(reference, "individual")
    with engine.connect() as conn:
        return engine, resolve_individual(conn, reference)


def lineage(
    individual: Annotated[str, typer.Argument(metavar="INDIVIDUAL", help=INDIVIDUAL_HELP)],
    as_json: JsonOption = False,
    db: DbOption = None,
) -> None:
    """An individual's ancestors, newest first, to its root newcomer."""
    from softevo.service.storage.status import lineage_records

    records = lineage_records(*one_individual(db, individual))
    if as_json:
        typer.echo(json.dumps(records, indent=2))
        return
    from rich.console import Console
    from rich.table import Table

    table = Table("id", "parent", "born", "environment", "distance", "active share", "voxels", "error")
    for r in records:
        table.add_row(
            str(r["id"]),
            str(r["parent_id"] or "-"),
            str(r["generation_born"]),
            str(r["environment"]),
            _fmt(r["distance"]),
            _fmt(r["active_share"]),
            str(r["voxel_count"]),
            r["error"] or "",
        )
    Console().print(table)


def best(
    reference: RunArgument,
    as_json: JsonOption = False,
    db: DbOption = None,
) -> None:
    """A run's best individual in each world it visited (greatest distance), in the order
    the run met them; the same as GET /runs/{id}/best."""
    from softevo.service.storage import open_database
    from softevo.service.storage.runs import best_per_world, resolve_run

    engine = open_database(db, create=False)
    say_bare_number(reference, "run")
    with engine.connect() as conn:
        run_id = resolve_run(conn, reference)
        rows = best_per_world(conn, run_id)
    if as_json:
        typer.echo(json.dumps(rows, indent=2))
        return
    if not rows:
        typer.echo(f"run {run_id} has no evaluated individual yet")
        return
    from rich.console import Console
    from rich.table import Table

    table = Table("world", "individual", "generation", "distance", "active share", "voxels",
                  title=f"run {run_id}: best per world")  # fmt: skip
    for r in rows:
        table.add_row(
            r["environment"],
            str(r["individual_id"]),
            str(r["generation"]),
            _fmt(r["distance"]),
            _fmt(r["active_share"]),
            str(r["voxel_count"]),
        )
    Console().print(table)


def _fmt(value: float | None) -> str:
    return "-" if value is None else f"{value:.3f}"


def register(app: typer.Typer) -> None:
    """Add this module's commands to ``app``."""
    for command in (run, experiment, status, resume, export, lineage, best):
        app.command(name=command.__name__)(command)
