"""``softevo report | show | export-vxa`` (SPEC.md section 7).

- ``softevo report EXPERIMENT --out DIR``: the HTML + Markdown report with every figure, the
  statistics and the run settings (``service.reports.write_report``).
- ``softevo show INDIVIDUAL --out FILE.gif|FILE.mp4``: re-simulate a stored individual and
  animate its motion (MP4 needs ffmpeg).
- ``softevo export-vxa INDIVIDUAL --out FILE.vxa``: the individual as a VoxCAD file.

EXPERIMENT is an id (``3``, ``e3``, ``exp-3``), ``latest`` or a name (the newest of that
name); INDIVIDUAL is an individual's database id (as ``softevo lineage`` and the exports
show). ``show`` and ``export-vxa`` use the environment of the individual's latest evaluation
unless ``--environment`` is given.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from softevo.errors import UserError
from softevo.service.cli_runs import DbOption

EnvironmentOption = Annotated[
    str | None,
    typer.Option("--environment", help="land | water (default: of its latest evaluation)"),
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
    from softevo.service.reports import write_report

    result = write_report(db, experiment, out, animation=animation, progress=not quiet)
    typer.echo(str(result.html))
    typer.echo(str(result.markdown))


def show(
    individual: Annotated[int, typer.Argument(metavar="INDIVIDUAL")],
    out: Annotated[Path, typer.Option("--out", help="FILE.gif or FILE.mp4")],
    environment: EnvironmentOption = None,
    fps: Annotated[int, typer.Option("--fps", help="playback frames per second")] = 20,
    db: DbOption = None,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="no progress bar")] = False,
) -> None:
    """Animate a stored individual's evaluated motion (re-simulated, frames recorded)."""
    from softevo.analysis.motion import animate, movie_writer, stored_motion
    from softevo.service.db import open_database
    from softevo.service.db.individuals import individual_record

    if fps < 1:
        raise UserError(f"--fps must be >= 1 (got {fps})")
    movie_writer(out, fps)  # a bad --out fails before the simulation
    motion = stored_motion(individual_record(open_database(db), individual), environment)
    with _frame_progress(not quiet) as on_frame:
        animate(motion, out, fps=fps, on_frame=on_frame)
    stored = "-" if motion.stored_distance is None else f"{motion.stored_distance:.4g}"
    typer.echo(f"{out}: {motion.label}, distance {motion.distance:.4g} voxel lengths (stored {stored})")


def export_vxa(
    individual: Annotated[int, typer.Argument(metavar="INDIVIDUAL")],
    out: Annotated[Path, typer.Option("--out", help="FILE.vxa")],
    environment: EnvironmentOption = None,
    db: DbOption = None,
) -> None:
    """Write a stored individual as a VoxCAD .vxa file."""
    from softevo.analysis.vxa import record_vxa
    from softevo.service.db import open_database
    from softevo.service.db.individuals import individual_record

    if out.suffix.lower() != ".vxa":
        raise UserError(f"--out must end in .vxa (got {out.name!r})")
    document = record_vxa(individual_record(open_database(db), individual), environment)
    try:
        out.write_text(document, encoding="iso-8859-1")
    except OSError as exc:
        raise UserError(f"cannot write {out}: {exc.strerror or exc}") from exc
    typer.echo(str(out))


def _frame_progress(enabled: bool):
    """A context giving ``on_frame(i, n)`` that drives a rich bar (or does nothing)."""
    from contextlib import contextmanager

    @contextmanager
    def bar():
        if not enabled:
            yield None
            return
        from rich.console import Console
        from rich.progress import Progress

        with Progress(console=Console(stderr=True), transient=True) as progress:
            task = progress.add_task("rendering frames", total=None)
            yield lambda i, n: progress.update(task, completed=i + 1, total=n)

    return bar()


def register(app: typer.Typer) -> None:
    """Add ``report``, ``show`` and ``export-vxa`` to ``app``."""
    app.command("report")(report)
    app.command("show")(show)
    app.command("export-vxa")(export_vxa)
