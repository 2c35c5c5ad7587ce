"""``softevo archive RUN [--generation G] [--environment WORLD] [--json]``: a run's MAP-Elites
archive, computed from its stored evaluations (``service.storage.archive.run_archive``; the
JSON is that of ``GET /runs/{id}/archive``).

The text shows the archive's coverage and QD score, the grid of cells of a two-measure
archive (the first measure across, the second upwards, each filled cell its elite's
distance, ``.`` an empty one) and the elites, at most ``SHOWN_ELITES`` of them (all with
``--json``).
"""

from __future__ import annotations

import json
from typing import Annotated

import typer

from softevo.errors import UserError
from softevo.service.cli.options import DbOption, JsonOption, RunArgument, say_bare_number

SHOWN_ELITES = 40
CELL_WIDTH = 7  # characters per cell of the grid (a space and 3 significant digits)


def archive(
    reference: RunArgument,
    generation: Annotated[
        int | None, typer.Option("--generation", help="the archive after this generation (default: the last)")
    ] = None,
    environment: Annotated[
        str | None,
        typer.Option("--environment", help="the archive of this world (default: the one evaluated at G)"),
    ] = None,
    as_json: JsonOption = False,
    db: DbOption = None,
) -> None:
    """A run's MAP-Elites archive: per cell of its measures, the farthest individual so far."""
    from softevo.service.storage import open_database
    from softevo.service.storage.archive import run_archive
    from softevo.service.storage.runs import resolve_run

    if generation is not None and generation < 0:
        raise UserError(f"--generation must be >= 0 (got {generation})")
    engine = open_database(db, create=False)
    say_bare_number(reference, "run")
    with engine.connect() as conn:
        summary = run_archive(conn, resolve_run(conn, reference), generation, environment)
    if as_json:
        typer.echo(json.dumps(summary, indent=1))
        return
    for line in archive_text(summary):
        typer.echo(line)


def archive_text(s: dict) -> list[str]:
    """The lines ``softevo archive`` prints for archive summary ``s``."""
    size = 1
    for count in s["cells"]:
        size *= count
    axes = ", ".join(f"{name} in [{low:g}, {high:g}] ({count} cells)"
                     for name, (low, high), count in zip(s["measures"], s["bounds"], s["cells"], strict=True))
    lines = [
        f"run {s['run']}, {s['environment']}, after generation {s['generation']}: {axes}",
        f"coverage {s['coverage']:.1%} ({s['filled']} of {size} cells), QD score {s['qd_score']:.4g}",
    ]
    if len(s["cells"]) == 2:
        lines += ["", *grid_lines(s)]
    lines += ["", f"{'cell':>10} {'individual':>10} {'distance':>9} {'gen':>4}  measures"]
    for elite in s["elites"][:SHOWN_ELITES]:
        cell = ",".join(map(str, elite["cell"]))
        values = " ".join(f"{name}={value:.4g}" for name, value in elite["measures"].items())
        ids = f"{cell:>10} {elite['individual']:>10}"
        lines.append(f"{ids} {elite['distance']:>9.4g} {elite['generation']:>4}  {values}")
    if len(s["elites"]) > SHOWN_ELITES:
        lines.append(f"... {len(s['elites']) - SHOWN_ELITES} more elites: --json lists them all")
    return lines


def grid_lines(s: dict) -> list[str]:
    """A two-measure archive as text: a row per cell of the second measure (its highest at
    the top), a column per cell of the first, each cell its elite's distance or ``.``."""
    across, up = s["cells"]
    held = {tuple(elite["cell"]): elite["distance"] for elite in s["elites"]}
    (low_x, high_x), (low_y, high_y) = s["bounds"]
    lines = [f"{s['measures'][1]} (up) by {s['measures'][0]} (across); each cell its elite's distance"]
    for row in reversed(range(up)):
        edge = low_y + (high_y - low_y) * (row + 1) / up
        cells = "".join(_cell(held.get((col, row))) for col in range(across))
        lines.append(f"{edge:>8.3g} |{cells}")
    width = CELL_WIDTH * across
    lines.append(f"{'':>8} +{'-' * width}")
    lines.append(f"{'':>8}  {low_x:<{width // 2}g}{high_x:>{width - width // 2}g}")
    return lines


def _cell(distance: float | None) -> str:
    text = "." if distance is None else f"{distance:.3g}"
    return f"{text:>{CELL_WIDTH}}"


def register(app: typer.Typer) -> None:
    """Add ``archive`` to ``app``."""
    app.command("archive")(archive)
