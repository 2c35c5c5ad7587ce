"""softevo: evolve soft voxel robots that walk on land and swim in water.

The project's folders install as one package: ``softevo.sim`` (the physics engine),
``softevo.evolution`` (CPPN encoding, AFPO), ``softevo.worker`` (tasks in, results out),
``softevo.service`` (SQL storage, coordinator, CLI, REST API), ``softevo.analysis``
(statistics, figures, reports) and ``softevo.migrations``.

For notebooks and scripts, five functions cover the common uses::

    import softevo
    from softevo.sim.worlds import WATER            # the registry's worlds (LAND, WATER, ...)
    result = softevo.simulate(scene)                 # a scene dict (docs/contracts.md) -> Result
    softevo.describe(body)                           # shape descriptors of a voxel array
    local = softevo.evolve(WATER.name, 0.1, generations=10)  # in memory: .best().scene, .history
    data = softevo.load_experiment("sqlite:///softevo.db", "latest")   # DataFrames
    scene = softevo.import_vxa("robot.vxa")          # a VoxCAD / evosoro file -> scene dict

Each imports its layer when called, so that ``import softevo.sim`` in a worker does not load
pandas, SQLAlchemy or the web stack.
"""

from __future__ import annotations

from typing import Any


def _installed_version() -> str:
    """The version of the installed package (pyproject.toml's, read from its metadata)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("softevo")
    except PackageNotFoundError:  # run from a source tree that was never installed
        return "0+unknown"


__version__ = _installed_version()
__all__ = ["describe", "evolve", "import_vxa", "load_experiment", "simulate", "simulate_many"]


def simulate(scene: dict[str, Any], **options: Any):
    """Simulate one scene (a dict, docs/spec.md section 1); returns a ``softevo.sim.Result``."""
    from softevo import sim

    return sim.simulate(scene, **options)


def simulate_many(scenes: list[dict[str, Any]], **options: Any):
    """Simulate many scenes in one call, one thread per robot; results in order."""
    from softevo import sim

    return sim.simulate_many(scenes, **options)


def describe(body, frequency: float | None = None) -> dict[str, Any]:
    """Shape descriptors (voxel count, active share, symmetry, branching, shape entropy, ...)
    of a 3-D voxel array (0 empty, 1 passive, 2 active)."""
    from softevo.evolution.descriptors import describe as describe_body

    return describe_body(body, frequency)


def import_vxa(path) -> dict[str, Any]:
    """The scene (a dict, ``"model": "voxcad-land-water"``) of a VoxCAD / evosoro ``.vxa``
    file; what the scene cannot hold is said by a ``softevo.analysis.vxa.VxaWarning``, and a
    file that cannot be read raises ``softevo.analysis.vxa.VxaError`` (a ``UserError``).
    The mapping: ``softevo.analysis.vxa_import``."""
    from softevo.analysis.vxa_import import import_vxa as read

    return read(path)


def evolve(
    environment: str | None = None,
    stiffness_mpa: float | None = None,
    *,
    population: int | None = None,
    generations: int | None = None,
    workspace: tuple[int, int, int] | None = None,
    cycles: int | None = None,
    seed: int = 0,
    switch_at: int | None = None,
    switch_over: int = 0,
    objectives: tuple[str, ...] = (),
    algorithm: str | None = None,
    measures: tuple[str, ...] | None = None,
    cells: tuple[int, ...] | None = None,
    measure_bounds: tuple[float, ...] | None = None,
    progress: bool = False,
):
    """A local run in memory (no database) of the treatment ``softevo run`` would store:
    AFPO over CPPN robots in ``environment`` (``land``, ``water``, or a transition
    ``land-water`` / ``water-land`` at ``switch_at``, default half-way: abrupt, or gradual over
    ``switch_over`` generations of compound worlds such as ``land>water@0.250``) at
    ``stiffness_mpa``, for ``generations`` generations (0 .. generations - 1), selecting on
    ``objectives`` (names of registered objectives, ``evolution.selection.OBJECTIVES``; empty:
    the paper's), with ``algorithm`` (a registered one, ``evolution.algorithm.names()``;
    default AFPO; ``map-elites`` over the grid of ``measures``, ``cells`` and
    ``measure_bounds``, docs/algorithm.md). Unset sizes are the quick start's
    (``evolution.treatments.QUICK_START``: land, 1 MPa, 8 robots of 5x5x5 for 8 generations of
    4 cycles).

    It asks, evaluates and tells as ``softevo run`` does: the tasks go through the workers'
    job function (``worker.evaluate.evaluate_generation``: each genome's failure its own,
    shape descriptors included), so with the same seed its generations are those ``softevo
    run`` stores. A ``softevo.errors.UserError`` says what is wrong with a setting.

    Returns an ``evolution.runner.LocalRun``: ``.best(world=None)`` (the best individual in
    a world, default the last: ``.distance`` and ``.scene``, a dict ``softevo.simulate``
    runs), ``.evolution`` (its ``population`` holds the survivors with their objectives) and
    ``.history`` (one row per generation: world, best and mean distance, survivors, failed).
    For stored, resumable runs use ``softevo run``."""
    from softevo.evolution.runner import LocalRun, generation_summary, record_best, run
    from softevo.evolution.treatments import QUICK_START, Treatment
    from softevo.worker.evaluate import evaluate_generation

    given = {"environment": environment, "stiffness_mpa": stiffness_mpa, "population": population,
             "generations": generations, "workspace": workspace, "cycles": cycles}
    sizes = {key: QUICK_START[key] if value is None else value for key, value in given.items()}
    sizes["workspace"] = tuple(sizes["workspace"])
    grid = {"measures": measures, "cells": cells, "measure_bounds": measure_bounds}
    chosen = {key: tuple(value) for key, value in grid.items() if value is not None}
    if algorithm is not None:
        chosen["algorithm"] = algorithm
    treatment = Treatment(**sizes, seed=seed, switch_at=switch_at, switch_over=switch_over,
                          objectives=tuple(objectives), **chosen)
    history: list[dict[str, Any]] = []
    bests: dict = {}

    def on_generation(done) -> None:
        history.append(generation_summary(done))
        record_best(bests, done)

    algo = run(
        treatment.evolution_config(seed),
        evaluate_generation,
        treatment.generations - 1,
        schedule=treatment.schedule(),
        on_generation=on_generation,
        progress=progress,
    )
    return LocalRun(algo, history, bests)


def load_experiment(db: str | None = None, experiment: str = "latest", generations=None):
    """A stored experiment as pandas DataFrames (``softevo.analysis.data.ExperimentData``:
    treatments, runs, generations, populations, evaluations). ``db``: a SQLAlchemy URL
    (default ``$SOFTEVO_DB`` or ``sqlite:///softevo.db``); ``experiment``: ``latest``, ``e2``,
    ``2`` or a name. By default every population and every evaluation (the rows of
    ``softevo export``); ``generations`` (a list) reads less, for experiments too large to
    read whole: the populations at those generations, at 0, at each run's last and at those
    the analyses use, and only their members' evaluations."""
    from softevo.service.reports.data import load_experiment as load
    from softevo.service.storage import open_database
    from softevo.service.storage.experiments import resolve_experiment

    engine = open_database(db, create=False)
    try:
        with engine.connect() as conn:
            experiment_id = resolve_experiment(conn, str(experiment))
        if generations is None:
            return load(engine, experiment_id, everything=True)
        return load(engine, experiment_id, generations=generations)
    finally:
        engine.dispose()
