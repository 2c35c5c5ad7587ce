"""Submit experiments: store a new experiment and its pending runs from treatments, within
the limits of one request and of the server (``service.runs.limits``)."""

from __future__ import annotations

from collections.abc import Sequence

from sqlalchemy import Connection, Engine

from softevo.errors import UserError
from softevo.evolution.treatments import Treatment, preset_grid, select_treatments
from softevo.service.runs.limits import check_experiment, generation_cost
from softevo.service.settings import Settings
from softevo.service.storage.experiments import (
    NewRun,
    NewTreatment,
    create_experiment,
    lock_new_experiments,
    unfinished_work,
)


def create(
    engine: Engine,
    name: str,
    treatments: Sequence[Treatment],
    preset: str | None = None,
    scale: str | None = None,
    settings: Settings | None = None,
) -> tuple[int, list[int]]:
    """Store an experiment with one pending run per repetition; return (id, run ids).
    UserError if it is over the budget (``service.runs.limits.check_experiment``: runs per
    request, voxel-steps per request and, with the server's unfinished runs, per server),
    names an objective not registered in this process, or names two treatments alike."""
    names = [t.name for t in treatments]
    alike = sorted({name for name in names if names.count(name) > 1})
    if alike:
        raise UserError(
            f"treatment names must differ within an experiment: {', '.join(alike)} (give each a name)"
        )
    for t in treatments:
        t.objective_list()  # UserError for an objective not registered here
    new = [
        NewTreatment(
            t.name,
            t.to_settings(),
            [NewRun(r, t.seed_of(r), t.generations) for r in range(t.repetitions)],
        )
        for t in treatments
    ]
    with engine.begin() as conn:
        lock_new_experiments(conn)  # the check and the insert as one: concurrent requests queue
        check_experiment(treatments, unfinished_cost(conn), settings)
        return create_experiment(conn, name, new, preset=preset, scale=scale)


def unfinished_cost(conn: Connection) -> float:
    """Voxel-steps the pending and running runs still have to do (``generation_cost`` x the
    generations each has left); settings ``Treatment.from_settings`` refuses count nothing."""
    total = 0.0
    for stored, generations_left in unfinished_work(conn):
        try:
            total += generation_cost(Treatment.from_settings(stored)) * generations_left
        except UserError:
            continue
    return total


def create_paper(
    engine: Engine,
    scale: str,
    repetitions: int | None = None,
    seed: int = 0,
    preset: str = "paper",
    only: Sequence[str] | None = None,
    name: str | None = None,
    **choices: str | None,
) -> tuple[int, list[int]]:
    """A preset's treatments (``evolution.treatments.PRESETS``; default the paper's grid,
    docs/spec.md section 5) at ``scale`` as a new experiment named ``name`` (default
    ``<preset>-<scale>``); ``only``: just the treatments of these names, with the seeds they
    have in the whole preset (``select_treatments``); ``choices`` (e.g. ``algorithm``,
    ``model``; None: the paper's) as ``preset_grid`` takes them."""
    treatments = preset_grid(preset, scale, repetitions=repetitions, seed=seed, **choices)
    if only is not None:
        treatments = select_treatments(treatments, only)
    return create(engine, name or f"{preset}-{scale}", treatments, preset=preset, scale=scale)
