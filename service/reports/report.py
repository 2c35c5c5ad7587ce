"""The experiment report from the database: resolve the experiment, read its
``ExperimentData``, bind the stored robots, and hand both to ``analysis.report``.

``write_report(source, experiment, out_dir)`` is what ``softevo report`` and the REST
service call; ``report_html(source, experiment)`` returns the page as a string.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pandas as pd
from sqlalchemy import Connection, Engine

from softevo.analysis import motion, robots
from softevo.analysis import report as analysis_report
from softevo.analysis.exaptation import ExaptationData
from softevo.analysis.qd import QD_COLUMNS
from softevo.analysis.report import Report, Robots
from softevo.evolution import traits
from softevo.service.reports.data import load_experiment
from softevo.service.storage import open_database
from softevo.service.storage.archive import run_qd_curve
from softevo.service.storage.exaptation import exaptation
from softevo.service.storage.experiments import evaluation_frequencies, resolve_experiment
from softevo.service.storage.individuals import individual_record, stored_genomes


def engine_of(source: str | Engine | Connection | Any | None) -> Engine:
    """An engine from a URL (None: the default database; one that does not exist is a
    UserError, not a new database), an Engine, a Connection or an ORM Session."""
    if isinstance(source, Engine):
        return source
    if isinstance(source, Connection):
        return source.engine
    if source is None or isinstance(source, str):
        return open_database(source, create=False)
    if hasattr(source, "get_bind"):
        return source.get_bind()
    raise TypeError(f"expected a database URL, Engine, Connection or Session, got {source!r}")


def stored_robots(engine: Engine, experiment_id: int | None = None) -> Robots:
    """The report's access to the robots stored in ``engine``'s database: each reads the
    individual's record (``service.storage.individuals.individual_record``) and hands it to
    ``analysis.robots`` / ``analysis.motion``."""

    def phenotypes(individual_ids):
        with engine.connect() as conn:
            stored = stored_genomes(conn, individual_ids)
        return {i: robots.develop_genome(genome, treatment) for i, (genome, treatment) in stored.items()}

    def scene(individual_id: int, environment: str | None = None, **extra: Any):
        return robots.record_scene(individual_record(engine, individual_id), environment, **extra)

    def stored_motion(individual_id: int, environment: str | None = None):
        return motion.stored_motion(individual_record(engine, individual_id), environment)

    def frequencies():
        return None if experiment_id is None else evaluation_frequencies(engine, experiment_id)

    return Robots(phenotypes=phenotypes, scene=scene, motion=stored_motion, evaluations=frequencies)


def exaptation_data(engine: Engine, data) -> ExaptationData:
    """``analysis.exaptation.ExaptationData`` of the experiment's transition runs that have
    passed their switch (``service.storage.exaptation.exaptation`` per run)."""
    transitions = set(data.treatments.loc[data.treatments["environment"].str.contains("-"), "name"])
    runs, founders, lines = [], [], []
    with engine.connect() as conn:
        for run_id in data.runs.loc[data.runs["treatment"].isin(transitions), "run_id"]:
            summary = exaptation(conn, int(run_id))
            if summary["generation"] < summary["switch_at"]:
                continue
            runs.append(
                {
                    key: summary[key]
                    for key in (
                        "run_id",
                        "switch_at",
                        "switch_over",
                        "arrival",
                        "generation",
                        "founders",
                        "founders_surviving",
                        "final_population",
                        "from_founders",
                    )
                }
                | {"lines": summary["lines_total"]}
            )
            for f in summary["founder_lines"]:
                founders.append(
                    {
                        "run_id": run_id,
                        "founder_id": f["founder_id"],
                        "lines": f["lines"],
                        "front_lines": f["front_lines"],
                        "surviving": f["lines"] > 0,
                        **f["traits"],
                    }
                )
            for line in summary["lines"]:
                row = {
                    "run_id": run_id,
                    "founder_id": line["founder_id"],
                    "individual_id": line["individual_id"],
                }
                for trait in traits.along_lines():
                    values = line["traits"][trait]
                    row |= {
                        f"{trait}_founder": values["founder"],
                        f"{trait}_switch": values["switch"],
                        f"{trait}_end": values["end"],
                        f"{trait}_changed": values["first_changed"],
                    }
                lines.append(row)
    return ExaptationData(pd.DataFrame(runs), pd.DataFrame(founders), pd.DataFrame(lines))


def qd_data(engine: Engine, data) -> pd.DataFrame:
    """Each run's archive coverage and QD score per stored generation
    (``service.storage.archive.run_qd_curve``), as ``analysis.qd.QD_COLUMNS``."""
    rows = []
    with engine.connect() as conn:
        for run_id in data.runs["run_id"]:
            rows += [{"run_id": int(run_id), **row} for row in run_qd_curve(conn, int(run_id))]
    return pd.DataFrame(rows, columns=list(QD_COLUMNS))


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
    ``service.storage.experiments.resolve_experiment``) into ``out_dir``; ``source``: a database URL,
    Engine, Connection or Session; ``options``: those of ``analysis.report.write_report``
    (animation, progress, seed)."""
    engine, data = _load(source, experiment)
    options.setdefault("exaptation", exaptation_data(engine, data))
    options.setdefault("qd", qd_data(engine, data))
    robots_of = stored_robots(engine, int(data.experiment["id"]))
    return analysis_report.write_report(data, out_dir, robots=robots_of, **options)


def report_html(source: str | Engine | Connection | Any | None, experiment: int | str) -> str:
    """The report page of ``experiment`` as a string, built in a temporary directory."""
    engine, data = _load(source, experiment)
    robots_of = stored_robots(engine, int(data.experiment["id"]))
    return analysis_report.report_html(data, robots_of, exaptation=exaptation_data(engine, data),
                                       qd=qd_data(engine, data))
