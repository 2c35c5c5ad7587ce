"""The experiment report from the database: resolve the experiment, read its
``ExperimentData``, bind the stored robots, and hand both to ``analysis.report``.

``write_report(source, experiment, out_dir)`` is what ``softevo report`` and the REST
service call; ``report_html(source, experiment)`` returns the page as a string.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from sqlalchemy import Connection, Engine

from softevo.analysis import motion, robots
from softevo.analysis import report as analysis_report
from softevo.analysis.report import Report, Robots
from softevo.service.db import open_database
from softevo.service.db.experiments import load_experiment, resolve_experiment
from softevo.service.db.individuals import individual_record, stored_genomes


def engine_of(source: str | Engine | Connection | Any | None) -> Engine:
    """An engine from a URL (None: the default database), an Engine, a Connection or an ORM
    Session."""
    if isinstance(source, Engine):
        return source
    if isinstance(source, Connection):
        return source.engine
    if source is None or isinstance(source, str):
        return open_database(source)
    if hasattr(source, "get_bind"):
        return source.get_bind()
    raise TypeError(f"expected a database URL, Engine, Connection or Session, got {source!r}")


def stored_robots(engine: Engine) -> Robots:
    """The report's access to the robots stored in ``engine``'s database: each reads the
    individual's record (``service.db.individuals.individual_record``) and hands it to
    ``analysis.robots`` / ``analysis.motion``."""

    def phenotypes(individual_ids):
        with engine.connect() as conn:
            stored = stored_genomes(conn, individual_ids)
        return {i: robots.develop_genome(*stored[i]) for i in stored}

    def scene(individual_id: int, environment: str | None = None, **extra: Any):
        return robots.record_scene(individual_record(engine, individual_id), environment, **extra)

    def stored_motion(individual_id: int, environment: str | None = None):
        return motion.stored_motion(individual_record(engine, individual_id), environment)

    return Robots(phenotypes=phenotypes, scene=scene, encoding=robots.encoding_of, motion=stored_motion)


def _load(source, experiment: int | str):
    engine = engine_of(source)
    with engine.connect() as conn:
        experiment_id = resolve_experiment(conn, str(experiment))
    return engine, load_experiment(engine, experiment_id)


def write_report(
    source: str | Engine | Connection | Any | None,
    experiment: int | str,
    out_dir: str | Path,
    **options: Any,
) -> Report:
    """Write the report of ``experiment`` (an id, ``e3``, ``latest`` or a name:
    ``service.db.experiments.resolve_experiment``) into ``out_dir``; ``source``: a database URL,
    Engine, Connection or Session; ``options``: those of ``analysis.report.write_report``
    (animation, progress, seed)."""
    engine, data = _load(source, experiment)
    return analysis_report.write_report(data, out_dir, robots=stored_robots(engine), **options)


def report_html(source: str | Engine | Connection | Any | None, experiment: int | str) -> str:
    """The report page of ``experiment`` as a string, built in a temporary directory."""
    engine, data = _load(source, experiment)
    return analysis_report.report_html(data, stored_robots(engine))
