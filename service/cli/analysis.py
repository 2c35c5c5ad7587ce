"""``softevo report | show | export-vxa | import-vxa | power`` (docs/spec.md section 7).

- ``softevo report EXPERIMENT --out DIR``: the HTML + Markdown report with every figure, the
  statistics and the run settings (``service.reports.report.write_report``).
- ``softevo show INDIVIDUAL --out FILE.gif|FILE.mp4``: re-simulate a stored individual and
  animate its motion (MP4 needs ffmpeg).
- ``softevo export-vxa INDIVIDUAL --out FILE.vxa``: the individual as a VoxCAD file.
- ``softevo import-vxa FILE.vxa --out SCENE.json``: a VoxCAD / evosoro file as a scene
  (``analysis.vxa_import``; what it cannot map: one ``warning:`` line each on stderr).
- ``softevo power EXPERIMENT``: from a pilot experiment's runs, the repetitions and
  generations the paper's comparisons need for the target power after Bonferroni
  (``analysis.power``).

EXPERIMENT is an id (``3``, ``e3``, ``exp-3``), ``latest`` or a name (the newest of that
name); INDIVIDUAL is an individual's database id (as ``softevo lineage`` and the exports
show), or a run (``latest``, ``r5``, a name: ``service.storage.runs.resolve_individual``) for its
best individual in its last world. ``show`` and ``export-vxa`` use the environment of the
individual's latest evaluation unless ``--environment`` is given.
"""

from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path
from typing import Annotated

import typer

from softevo.errors import UserError
from softevo.evolution import environments
from softevo.service.cli.options import INDIVIDUAL_HELP, DbOption, JsonOption, say_bare_number
from softevo.service.cli.runs import one_individual

EnvironmentOption = Annotated[
    str | None,
    typer.Option(
        "--environment",
        help=f"{' | '.join(environments.names(evolve=True))} (default: of its latest evaluation)",
    ),
]


def report(
    experiment: Annotated[str, typer.Argument(metavar="EXPERIMENT", help="id, e3, latest or name")],
    out: Annotated[Path, typer.Option("--out", help="output directory")],
    db: DbOption = None,
    animation: Annotated[
        bool, typer.Option("--animation/--no-animation", help="include the best robot's GIF")
    ] = True,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="no progress bar")] = False,
) -> None:
    """Write an experiment's report: report.html (self-contained), report.md, figures, CSVs."""
    # the report pulls in matplotlib and the analyses: load them only for this command
    from softevo.analysis.report import ReportWarning
    from softevo.service.reports.report import write_report

    say_bare_number(experiment, "experiment")
    with _warning_lines(ReportWarning):
        result = write_report(db, experiment, out, animation=animation, progress=not quiet)
    typer.echo(str(result.html))
    typer.echo(str(result.markdown))


def show(
    individual: Annotated[str, typer.Argument(metavar="INDIVIDUAL", help=INDIVIDUAL_HELP)],
    out: Annotated[Path, typer.Option("--out", help="FILE.gif or FILE.mp4")],
    environment: EnvironmentOption = None,
    fps: Annotated[int, typer.Option("--fps", help="playback frames per second")] = 20,
    db: DbOption = None,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="no progress bar")] = False,
) -> None:
    """Animate a stored individual's evaluated motion (re-simulated, frames recorded)."""
    from softevo.analysis.motion import animate, movie_writer, stored_motion
    from softevo.service.storage.individuals import individual_record

    if fps < 1:
        raise UserError(f"--fps must be >= 1 (got {fps})")
    movie_writer(out, fps)  # a bad --out fails before the simulation
    motion = stored_motion(individual_record(*one_individual(db, individual)), environment)
    with _frame_progress(not quiet) as on_frame:
        animate(motion, out, fps=fps, on_frame=on_frame)
    stored = "-" if motion.stored_distance is None else f"{motion.stored_distance:.4g}"
    typer.echo(f"{out}: {motion.label}, distance {motion.distance:.4g} voxel lengths (stored {stored})")


def export_vxa(
    individual: Annotated[str, typer.Argument(metavar="INDIVIDUAL", help=INDIVIDUAL_HELP)],
    out: Annotated[Path, typer.Option("--out", help="FILE.vxa")],
    environment: EnvironmentOption = None,
    db: DbOption = None,
) -> None:
    """Write a stored individual as a VoxCAD .vxa file."""
    from softevo.analysis.vxa import record_vxa
    from softevo.service.storage.individuals import individual_record

    if out.suffix.lower() != ".vxa":
        raise UserError(f"--out must end in .vxa (got {out.name!r})")
    with _warning_lines():
        document = record_vxa(individual_record(*one_individual(db, individual)), environment)
    try:
        out.write_text(document, encoding="iso-8859-1")
    except OSError as exc:
        raise UserError(f"cannot write {out}: {exc.strerror or exc}") from exc
    typer.echo(str(out))


def import_vxa(
    vxa: Annotated[Path, typer.Argument(metavar="FILE.vxa", help="a VoxCAD / evosoro file")],
    out: Annotated[Path, typer.Option("--out", help="SCENE.json")],
) -> None:
    """Read a VoxCAD / evosoro .vxa file as a scene (JSON) for softevo simulate."""
    import json

    from softevo.analysis.vxa_import import read_vxa

    if out.suffix.lower() != ".json":
        raise UserError(f"--out must end in .json (got {out.name!r})")
    imported = read_vxa(vxa)
    for message in imported.warnings:
        typer.echo(f"warning: {message}", err=True)
    try:
        out.write_text(json.dumps(imported.scene) + "\n", encoding="utf-8")
    except OSError as exc:
        raise UserError(f"cannot write {out}: {exc.strerror or exc}") from exc
    typer.echo(str(out))


@contextmanager
def _warning_lines(*categories: type[Warning]):
    """Print each warning of ``categories`` (default ``VxaWarning``) raised inside as one
    ``warning:`` line on stderr."""
    import warnings

    from softevo.analysis.vxa import VxaWarning

    categories = categories or (VxaWarning,)
    with warnings.catch_warnings(record=True) as caught:
        for category in categories:
            warnings.simplefilter("always", category)
        yield
    for warning in caught:
        if issubclass(warning.category, categories):
            typer.echo(f"warning: {warning.message}", err=True)
        else:
            warnings.warn_explicit(warning.message, warning.category, warning.filename, warning.lineno)


def power(
    experiment: Annotated[
        str, typer.Argument(metavar="EXPERIMENT", help="the pilot: id, e3, latest or name")
    ],
    alpha: Annotated[float, typer.Option("--alpha", help="significance level before Bonferroni")] = 0.05,
    target: Annotated[float, typer.Option("--power", help="target power")] = 0.8,
    max_n: Annotated[int, typer.Option("--max-n", help="most repetitions per treatment tried")] = 50,
    family: Annotated[
        int | None,
        typer.Option("--family", help="tests per Bonferroni family (default: each comparison's family)"),
    ] = None,
    study_n: Annotated[
        int | None,
        typer.Option("--study-n", help="the planned study's repetitions (default: the study preset's)"),
    ] = None,
    seed: Annotated[int, typer.Option("--seed", help="seed of the simulated studies")] = 0,
    as_json: JsonOption = False,
    db: DbOption = None,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="no progress bar")] = False,
) -> None:
    """Repetitions (and generations) the paper's comparisons need, from a pilot's runs, at a
    lower confidence bound of each effect; the exact-p floor and the detectable effect per n."""
    import json

    from softevo.analysis.power import (
        PowerSettings,
        design_table,
        estimate_power,
        estimate_steps,
        missing,
        power_generations,
    )
    from softevo.evolution.treatments import preset_scale
    from softevo.service.reports.data import load_experiment
    from softevo.service.reports.report import engine_of
    from softevo.service.storage.experiments import resolve_experiment

    study_n = preset_scale("study").repetitions if study_n is None else study_n
    settings = PowerSettings(
        alpha=alpha, power=target, max_n=max_n, family_size=family, study_n=study_n, seed=seed
    )
    settings.validate()
    engine = engine_of(db)
    say_bare_number(experiment, "experiment")
    with engine.connect() as conn:
        experiment_id = resolve_experiment(conn, experiment)
    data = load_experiment(engine, experiment_id)
    if not data.generations.empty:
        data = load_experiment(engine, experiment_id, generations=power_generations(data))
    with _steps_progress(not quiet, estimate_steps(data, settings)) as on_step:
        estimates = estimate_power(data, settings, on_step)
    thresholds = sorted({e.alpha_bonferroni for e in estimates}, reverse=True)
    designs = {a: design_table(a, target, ns=_design_ns(max_n)) for a in thresholds}
    if as_json:
        payload = {
            "experiment": experiment_id,
            "settings": {"alpha": alpha, "power": target, "max_n": max_n, "study_n": study_n, "seed": seed},
            "comparisons": [e.to_dict() for e in estimates],
            "designs": [row for a in thresholds for row in designs[a].to_dict("records")],
            "not_in_experiment": missing(data),
        }
        typer.echo(json.dumps(payload, indent=2))
        return
    typer.echo(
        f"pilot e{experiment_id} \u201c{data.experiment['name']}\u201d: target power {target:g}, "
        f"alpha {alpha:g} / each comparison's family; the effect taken at the lower end of its "
        "80% interval from the pilot (normal model), tested by Mann-Whitney U (independent seeds)"
    )
    for e in estimates:
        typer.echo(_estimate_line(e))
    for name in missing(data):
        typer.echo(f"{name}: not in this experiment")
    for a in thresholds:
        typer.echo(f"design at alpha {a:.3g}: n, exact-p floor, smallest A12 detectable at power {target:g}")
        for row in designs[a].itertuples():
            detectable = row.detectable_a12_mann_whitney
            shown = "none (floor)" if detectable != detectable else f"{detectable:.2f}"
            typer.echo(f"  n={row.n}: floor {row.floor_mann_whitney:.2g}, detectable A12 {shown}")


def _design_ns(max_n: int) -> tuple[int, ...]:
    from softevo.analysis.power import DESIGN_NS

    return tuple(n for n in DESIGN_NS if n < max_n) + (max_n,)


def _estimate_line(e) -> str:
    """One comparison's estimate, a "no difference" with the smallest effect detectable."""
    reps = f"{e.repetitions} repetitions" if e.repetitions else f"more than {e.max_n} repetitions"
    gens = (
        f"{e.generations} of {e.pilot_generations} generations"
        if e.generations
        else f"more than the pilot's {e.pilot_generations} generations"
    )
    detectable = (
        "no A12 (exact-p floor)"
        if e.detectable_a12 != e.detectable_a12
        else (f"A12 >= {e.detectable_a12:.2f} or <= {1 - e.detectable_a12:.2f}")
    )
    verdict = (
        "no effect the pilot can vouch for (its 80% interval holds none)"
        if e.shift_low == 0
        else f"effect at least A12 {e.a12_low:.2f} (80% interval's nearer end)"
    )
    return (
        f"{e.comparison} [{e.family}, {e.family_size} tests, alpha {e.alpha_bonferroni:.3g}]: {reps} per "
        f"treatment (power {e.power:.2f}; {e.power_at_estimate:.2f} at the pilot's point estimate), "
        f"{gens}; {verdict}; a study of {e.study_n} per treatment: power {e.power_at_study_n:.2f}, "
        f"detects {detectable}; the exact-p floor falls below alpha from n={e.floor_n}; pilot {e.a} "
        f"vs {e.b} at generation {e.generation}: {e.pilot_runs_a}+{e.pilot_runs_b} runs (seeds "
        f"{e.pilot_seeds}: the study must use others), means {e.pilot_mean_a:.3g} vs "
        f"{e.pilot_mean_b:.3g}, A12 {e.pilot_a12:.2f}, p {e.pilot_p:.3g}"
    )


@contextmanager
def _progress(enabled: bool, title: str, total: int | None = None):
    """A transient rich bar on stderr, yielding ``update(**fields)`` (None when disabled)."""
    if not enabled:
        yield None
        return
    from rich.console import Console
    from rich.progress import Progress

    with Progress(console=Console(stderr=True), transient=True) as progress:
        task = progress.add_task(title, total=total)
        yield lambda **fields: progress.update(task, **fields)


@contextmanager
def _steps_progress(enabled: bool, total: int):
    """``on_step(description)`` advancing a bar of ``total`` steps (None when disabled)."""
    with _progress(enabled, "power", total) as update:
        yield update and (lambda description: update(advance=1, description=description))


@contextmanager
def _frame_progress(enabled: bool):
    """``on_frame(i, n)`` driving a bar of rendered frames (None when disabled)."""
    with _progress(enabled, "rendering frames") as update:
        yield update and (lambda i, n: update(completed=i + 1, total=n))


def register(app: typer.Typer) -> None:
    """Add ``report``, ``show``, ``export-vxa``, ``import-vxa`` and ``power`` to ``app``."""
    app.command("report")(report)
    app.command("power")(power)
    app.command("show")(show)
    app.command("export-vxa")(export_vxa)
    app.command("import-vxa")(import_vxa)
