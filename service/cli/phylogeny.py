"""``softevo phylogeny | exaptation``: a run's tree, and what survived its transition.

- ``softevo phylogeny RUN [--generation G] [--json | --csv]``: every individual of the run
  (as it stood at generation ``G`` if given): id, parent, generation born, last generation
  kept, environment and every trait at birth (``evolution.traits``, registered ones included;
  ``service.storage.run_tree.run_phylogeny``), read page by page; the table, to fit a
  terminal, shows the paper's three objectives and the traits a deployment registered.
- ``softevo exaptation RUN [--json]``: for a transition run, the founders kept at the switch,
  how many of their lines reach the last generation, the roots of the final population and,
  per surviving line, each trait it follows (``evolution.traits.along_lines()``) at the
  founder, at the switch and at the end with the
  generation each first changed (``service.storage.exaptation.exaptation``; the JSON is that of
  ``GET /runs/{id}/exaptation`` without paging).

RUN is a run id (``5``, ``r5``, ``run-5``), or ``latest``, ``e2`` or an experiment's name
for an experiment of one run (``service.storage.runs.resolve_run``). ``docs/sql.md`` gives the
same as SQL.
"""

from __future__ import annotations

import csv
import json
import sys
from typing import Annotated

import typer

from softevo.errors import UserError
from softevo.evolution import traits
from softevo.service.cli.options import DbOption, JsonOption, RunArgument, say_bare_number

PAGE = 10_000
NODE_COLUMNS = ("id", "parent_id", "generation_born", "last_generation", "environment")  # then the traits


def phylogeny_columns() -> tuple[str, ...]:
    """The columns of ``softevo phylogeny --csv``: ``NODE_COLUMNS`` and every registered trait."""
    return (*NODE_COLUMNS, *traits.names())


def line_headers() -> dict[str, str]:
    """{trait: its short title} of the traits the exaptation table follows along lines."""
    headers = traits.headers()
    return {name: headers[name] for name in traits.along_lines()}


def phylogeny(
    reference: RunArgument,
    generation: Annotated[
        int | None, typer.Option("--generation", help="the tree as it stood at this generation")
    ] = None,
    as_json: JsonOption = False,
    as_csv: Annotated[bool, typer.Option("--csv", help="print CSV")] = False,
    db: DbOption = None,
) -> None:
    """A run's phylogeny: every individual with its parent, birth, last generation kept,
    environment and traits at birth."""
    from softevo.service.storage import open_database
    from softevo.service.storage.run_tree import run_phylogeny
    from softevo.service.storage.runs import resolve_run, run_row

    if as_json and as_csv:
        raise UserError("give --json or --csv, not both")
    if generation is not None and generation < 0:
        raise UserError(f"--generation must be >= 0 (got {generation})")
    engine = open_database(db, create=False)
    say_bare_number(reference, "run")
    rows = []
    with engine.connect() as conn:
        run_id = resolve_run(conn, reference)
        last = run_row(conn, run_id)["generation"]
        if generation is not None and generation > last:
            stored = "no generation yet" if last < 0 else f"generations 0..{last}"
            raise UserError(f"--generation {generation} is past run {run_id}'s last: it has stored {stored}")
        total, offset = None, 0
        while total is None or offset < total:
            total, page = run_phylogeny(conn, run_id, generation, limit=PAGE, offset=offset)
            rows.extend(page)
            offset += PAGE
    if as_json:
        typer.echo(json.dumps(rows, indent=1))
    elif as_csv:
        writer = csv.DictWriter(sys.stdout, fieldnames=phylogeny_columns(), lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)
    else:
        _phylogeny_table(run_id, rows)


def _phylogeny_table(run_id: int, rows: list[dict]) -> None:
    from rich.console import Console
    from rich.table import Table

    from softevo.service.storage.run_tree import NODE_OBJECTIVES

    titles = traits.headers()
    headers = {name: titles[name] for name in (*NODE_OBJECTIVES, *traits.registered())}
    table = Table("id", "parent", "born", "last kept", "environment", *headers.values(),
                  title=f"run {run_id}: {len(rows)} individuals",
                  caption="every trait: --json or --csv")  # fmt: skip
    for r in rows:
        table.add_row(
            str(r["id"]),
            _cell(r["parent_id"]),
            str(r["generation_born"]),
            _cell(r["last_generation"]),
            _cell(r["environment"]),
            *[_cell(r.get(name)) for name in headers],
        )
    Console().print(table)


def exaptation(
    reference: RunArgument,
    as_json: JsonOption = False,
    db: DbOption = None,
) -> None:
    """For a transition run: the founders kept at the switch, which of their lines survive
    to the end, and the traits of each surviving line at the founder, the switch and the end."""
    from softevo.service.storage import open_database
    from softevo.service.storage.exaptation import exaptation as summary_of
    from softevo.service.storage.runs import resolve_run

    engine = open_database(db, create=False)
    with engine.connect() as conn:
        say_bare_number(reference, "run")
        summary = summary_of(conn, resolve_run(conn, reference))
    if as_json:
        typer.echo(json.dumps(summary, indent=1))
        return
    _exaptation_tables(summary)


def _exaptation_tables(s: dict) -> None:
    from rich.console import Console
    from rich.table import Table

    console = Console()
    old, new = s["environments"]
    gradual = f", over {s['switch_over']} generations" if s["switch_over"] else ""
    console.print(
        f"run {s['run_id']}: {old} -> {new} at generation {s['switch_at']}{gradual}; "
        f"last generation {s['generation']}\n"
        f"founders (kept at {s['switch_at'] - 1}): {s['founders']}, with lines to the end: "
        f"{s['founders_surviving']}\n"
        f"final population: {s['final_population']}, descending from founders: {s['from_founders']}; "
        f"root newcomers: {', '.join(map(str, s['roots']))}"
        f"{'' if s['every_line_rooted'] else ' (some ancestry does not reach a newcomer!)'}"
    )
    founders = Table("founder", "lines to the end", "on the final front", title="founders")
    for f in s["founder_lines"]:
        founders.add_row(str(f["founder_id"]), str(f["lines"]), str(f["front_lines"]))
    console.print(founders)
    console.print(lines_note(s))
    # a row per line and trait, so that the table fits 80 columns
    title = "surviving lines: each trait at the founder, the switch and the end"
    lines = Table("founder > final", "root", "trait", "founder", "switch", "end", "changed", title=title)
    headers = line_headers()
    for line in s["lines"]:
        for k, (trait, header) in enumerate(headers.items()):
            t = line["traits"][trait]
            ids = ("", "")
            if k == 0:
                ids = (f"{line['founder_id']} > {line['individual_id']}", str(line["root_id"]))
            changed = "-" if t["first_changed"] is None else f"gen {t['first_changed']}"
            values = (_cell(t["founder"]), _cell(t["switch"]), _cell(t["end"]), changed)
            lines.add_row(*ids, header, *values, end_section=k == len(headers) - 1)
    console.print(lines)


def lines_note(s: dict) -> str:
    """Why the founders' lines can add up to more than the final population: founders kept
    at the switch can descend from one another, and a final member counts once under each
    founder in its ancestry."""
    total = sum(f["lines"] for f in s["founder_lines"])
    return (
        f"lines to the end: {total} over {s['final_population']} final members; a final member "
        "counts once under each founder among its ancestors (a founder can descend from another "
        "founder kept at the switch), so the column can add up to more than the final population"
    )


def _cell(value) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.3g}"
    return str(value)


def register(app: typer.Typer) -> None:
    """Add ``phylogeny`` and ``exaptation`` to ``app``."""
    app.command("phylogeny")(phylogeny)
    app.command("exaptation")(exaptation)
