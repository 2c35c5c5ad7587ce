"""A run's MAP-Elites archive, computed from its stored evaluations (``run_archive``).

The archive after generation ``g`` is ``evolution.archive.elites`` over the run's
evaluations of generations ``0 .. g`` in the order they were evaluated: by generation, then
by individual id within a generation. It needs no table of its own and works on any run
(``map-elites``, ``afpo``, ``pareto``): the elite of a cell is the farthest evaluation whose
measures fall in it, the earliest among equals. Distance and the measures are read from the
evaluations table (a built-in trait's column, a registered trait's value in
``descriptors``: ``service.storage.trait_sql``).

Worlds: distances in two worlds do not compare, so an archive holds the evaluations of one
world (``evaluations.environment``). By default that is the world the run evaluated at
generation ``g`` (for a land -> water run past its switch, water: the archive the algorithm
is filling now); ``world`` picks another world the run evaluated in (``environment`` in the
JSON, ``--environment`` and ``?environment=`` on the command line and REST; ``environments``
lists them in the order the run met them; a gradual switch's compound worlds are worlds of
their own).
``history`` gives the coverage and QD score of the same world's archive after each stored
generation ``0 .. g`` (zero before the run first evaluated there).

The grid comes from the run's stored treatment settings (``grid_from_settings``: the
treatment's ``evolution.archive.grid_of``): the ``map-elites`` options ``measures``, ``cells``
and ``measure_bounds`` where stored, else their declared defaults, so that the archive of a run
of any algorithm can be drawn.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from sqlalchemy import Connection, func, select

from softevo.errors import UserError
from softevo.evolution.archive import Candidate, Grid, coverage, elites, grid_of, qd_score, summary
from softevo.evolution.treatments import Treatment
from softevo.service.storage.models import EvaluationRow, GenerationRow, RunRow, TreatmentRow
from softevo.service.storage.rows import finite
from softevo.service.storage.trait_sql import trait_values


def grid_from_settings(settings: Mapping[str, Any]) -> Grid:
    """The grid of a run's stored treatment ``settings`` (``evolution.archive.grid_of`` of the
    treatment they describe: the ``map-elites`` options where stored, else their defaults,
    so that the archive of a run of any algorithm can be drawn). UserError for settings that
    do not make a grid."""
    try:
        return grid_of(Treatment.from_settings(dict(settings)))
    except ValueError as exc:
        raise UserError(f"the run's archive grid: {exc}") from exc


def _run_settings(conn: Connection, run_id: int) -> tuple[dict[str, Any], int]:
    """(stored treatment settings, last stored generation) of run ``run_id``; UserError for
    an unknown run."""
    runs, treatments = RunRow.__table__, TreatmentRow.__table__
    row = conn.execute(
        select(treatments.c.settings, runs.c.generation)
        .join(treatments, runs.c.treatment_id == treatments.c.id)
        .where(runs.c.id == run_id)
    ).first()
    if row is None:
        raise UserError(f"no run {run_id}")
    return dict(row.settings or {}), int(row.generation)


def run_worlds(conn: Connection, run_id: int) -> list[str]:
    """The worlds run ``run_id`` evaluated in, in the order it first did."""
    ev = EvaluationRow.__table__
    first = func.min(ev.c.generation)
    rows = conn.execute(
        select(ev.c.environment, first).where(ev.c.run_id == run_id).group_by(ev.c.environment)
        .order_by(first, ev.c.environment)
    ).all()
    return [row.environment for row in rows]


def world_at(conn: Connection, run_id: int, generation: int) -> str | None:
    """The world run ``run_id`` evaluated in at ``generation`` (None if not stored)."""
    gen = GenerationRow.__table__
    return conn.execute(
        select(gen.c.environment).where(gen.c.run_id == run_id, gen.c.generation == generation)
    ).scalar()


def candidates(conn: Connection, run_id: int, grid: Grid, world: str, generation: int) -> list[Candidate]:
    """The evaluations of run ``run_id`` in ``world`` of generations ``0 .. generation`` as
    archive candidates, in the order they were evaluated (generation, then individual id)."""
    ev = EvaluationRow.__table__
    try:
        values = trait_values(grid.measures)
    except KeyError as exc:
        raise UserError(f"the run's archive measures: {exc.args[0]}") from exc
    query = (
        select(ev.c.individual_id, ev.c.generation, ev.c.distance, *values)
        .where(ev.c.run_id == run_id, ev.c.environment == world, ev.c.generation <= generation)
        .order_by(ev.c.generation, ev.c.individual_id)
    )
    return [
        Candidate(int(row["individual_id"]), row["distance"], {name: row[name] for name in grid.measures},
                  int(row["generation"]))
        for row in conn.execute(query).mappings()
    ]


def history(grid: Grid, ordered: Sequence[Candidate], generation: int) -> tuple[dict, list[dict[str, Any]]]:
    """(the archive after ``generation``, [{generation, coverage, qd_score, filled}] after each
    generation 0 .. ``generation``) of candidates ``ordered`` by generation."""
    archive: dict = {}
    rows, position = [], 0
    for g in range(generation + 1):
        end = position
        while end < len(ordered) and ordered[end].generation <= g:
            end += 1
        archive = elites(grid, ordered[position:end], archive)
        position = end
        rows.append({"generation": g, "coverage": coverage(grid, archive), "qd_score": qd_score(archive),
                     "filled": len(archive)})
    return archive, rows


def run_archive(
    conn: Connection, run_id: int, generation: int | None = None, world: str | None = None
) -> dict[str, Any]:
    """The archive of run ``run_id`` after ``generation`` (default the last stored) in
    ``world`` (default the one evaluated at that generation): ``evolution.archive.summary``
    (measures, bounds, cells, coverage, qd_score, filled, elites) with ``run``,
    ``generation``, ``environment`` (the world), ``environments`` (every world the run evaluated
    in) and ``history`` (module doc). UserError for an
    unknown run, a run with no generation stored, a generation not stored or a world the run
    never evaluated in."""
    settings, last = _run_settings(conn, run_id)
    if last < 0:
        raise UserError(f"run {run_id} has stored no generation yet")
    if generation is None:
        generation = last
    if not 0 <= generation <= last:
        raise UserError(f"run {run_id} has stored generations 0..{last}, not {generation}")
    worlds = run_worlds(conn, run_id)
    if world is None:
        world = world_at(conn, run_id, generation) or worlds[-1]
    elif world not in worlds:
        raise UserError(f"run {run_id} evaluated in {', '.join(worlds)}, not {world!r}")
    grid = grid_from_settings(settings)
    archive, per_generation = history(grid, candidates(conn, run_id, grid, world, generation), generation)
    return finite({"run": run_id, "generation": generation, "environment": world, "environments": worlds,
                   **summary(grid, archive), "history": per_generation})


def run_qd_curve(conn: Connection, run_id: int) -> list[dict[str, Any]]:
    """After each stored generation of run ``run_id``, the coverage and QD score of the
    archive of the world evaluated at that generation (the archive the run was filling then;
    a transition's curve moves on to its new world's archive): [{generation, environment,
    coverage, qd_score, filled}]; empty before any generation. UserError for an unknown run."""
    settings, last = _run_settings(conn, run_id)
    if last < 0:
        return []
    grid = grid_from_settings(settings)
    gen = GenerationRow.__table__
    evaluated = dict(conn.execute(
        select(gen.c.generation, gen.c.environment).where(gen.c.run_id == run_id, gen.c.generation <= last)
    ).all())
    per_world = {world: history(grid, candidates(conn, run_id, grid, world, last), last)[1]
                 for world in set(evaluated.values())}
    return [{"environment": evaluated[g], **per_world[evaluated[g]][g]} for g in sorted(evaluated)]
