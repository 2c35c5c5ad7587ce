"""Export runs to the files of docs/spec.md section 7: runs, individuals, populations.

``individuals`` has one row per evaluation (an individual re-evaluated at an environment
switch appears twice). CSV by default; Parquet needs ``pyarrow``.

``table_chunks(conn, table, run_ids)`` reads one table a bounded number of rows at a time,
with its final columns and types: ``export_runs`` (``softevo export``) writes whole files
from it, ``service.storage.export_stream`` streams it over REST, so both give the same rows.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from pathlib import Path

import pandas as pd
from sqlalchemy import Boolean, Connection, Engine, Float, Integer, Select, func, select

from softevo.errors import UserError
from softevo.evolution import traits
from softevo.evolution.treatments import PAPER_CHOICES, Treatment
from softevo.service.storage.models import (
    EvaluationRow,
    GenerationRow,
    IndividualRow,
    PopulationMemberRow,
    RunRow,
    TreatmentRow,
)
from softevo.service.storage.status import run_summary_select

FORMATS = ("csv", "parquet")
RUN_COLUMNS = [
    "run_id",
    "experiment",
    "treatment",
    "repetition",
    "seed",
    "environment_schedule",
    "stiffness_pa",
    "population",
    "generations",
    "generations_run",
    "status",
    "workspace",
    "switch_at",
    "cycles",
    "max_seconds",
    "settle_seconds",
    *PAPER_CHOICES,  # the choices the paper presets make: model, mapping, body rule, algorithm
    "created_at",
    "last_stored_at",
]
POPULATION_COLUMNS = ["run_id", "generation", "individual_id", "front_rank"]
TABLES = ("runs", "individuals", "populations")
CHUNK_ROWS = 20_000  # rows read, converted and written at a time


def _read(conn: Connection, query) -> pd.DataFrame:
    result = conn.execute(query)
    return pd.DataFrame(result.fetchall(), columns=list(result.keys()))


def runs_frame(conn: Connection, run_ids: Sequence[int]) -> pd.DataFrame:
    """One row per run: treatment settings flattened to the export columns (the evaluation's
    protocol included: cycles, the cap on seconds, settling per world as ``land:0.5``, the
    choices the paper presets make, ``PAPER_CHOICES``: model, mapping, body rule, algorithm;
    and the switch generation of a transition).
    ``generations`` is what the treatment planned, ``generations_run`` what the run stored
    (its last stored generation + 1; 0 before generation 0): less for a run that stopped
    early (failed, cancelled, interrupted)."""
    query = run_summary_select().add_columns(TreatmentRow.__table__.c.settings)
    frame = _read(conn, query.where(RunRow.__table__.c.id.in_(list(run_ids))))
    frame["generations_run"] = pd.array([max(int(g) + 1, 0) for g in frame["generation"]], dtype="Int64")
    settings = [Treatment.from_settings(s) for s in frame.pop("settings")]
    frame["environment_schedule"] = [t.schedule_text() for t in settings]
    frame["stiffness_pa"] = [t.stiffness_pa for t in settings]
    frame["population"] = [t.population for t in settings]
    frame["workspace"] = ["x".join(map(str, t.workspace)) for t in settings]
    frame["switch_at"] = pd.array([t.switch_generation() for t in settings], dtype="Int64")
    frame["cycles"] = [t.cycles for t in settings]
    frame["max_seconds"] = pd.array([t.max_seconds for t in settings], dtype="Float64")
    frame["settle_seconds"] = [
        ",".join(f"{world}:{seconds:g}" for world, seconds in t.settle_seconds().items()) for t in settings
    ]
    for name in PAPER_CHOICES:
        frame[name] = [getattr(t, name) for t in settings]
    frame = frame.merge(_times(conn, run_ids), on="run_id", how="left")
    return frame[RUN_COLUMNS]


def _times(conn: Connection, run_ids: Sequence[int]) -> pd.DataFrame:
    """Per run: ``created_at`` (submitted) and ``last_stored_at`` (its last generation
    stored; empty before any), ISO 8601 in UTC: the experiment's wall time is the span from
    the first to the last."""
    runs, generations = RunRow.__table__, GenerationRow.__table__
    last = (select(generations.c.run_id, func.max(generations.c.created_at).label("last_stored_at"))
            .group_by(generations.c.run_id).subquery())
    query = (select(runs.c.id.label("run_id"), runs.c.created_at, last.c.last_stored_at)
             .outerjoin(last, last.c.run_id == runs.c.id).where(runs.c.id.in_(list(run_ids))))
    frame = _read(conn, query)
    for column in ("created_at", "last_stored_at"):
        frame[column] = pd.array([_iso(v) for v in frame[column]], dtype="string")
    return frame


def _iso(value) -> str | None:
    """A stored time as ISO 8601 in UTC (SQLite gives it back without a zone)."""
    if value is None or value is pd.NaT or (isinstance(value, float) and math.isnan(value)):
        return None
    stamp = pd.Timestamp(value)
    stamp = stamp.tz_localize("UTC") if stamp.tzinfo is None else stamp.tz_convert("UTC")
    return stamp.isoformat()


IDENTITY_COLUMNS = ["individual_id", "run_id", "parent_id", "generation", "generation_born", "age",
                    "environment"]


def individual_columns() -> list[str]:
    """The columns of the export's ``individuals`` file (one row per evaluation): the
    individual and evaluation, every trait (``evolution.traits``, the registered ones read
    from the evaluation's ``descriptors``), ``stable``, ``error`` and its cost
    (``COST_COLUMNS``)."""
    return [*IDENTITY_COLUMNS, *traits.names(), "stable", "error", *COST_COLUMNS]


COST_COLUMNS = ["steps", "simulated_seconds", "wall_seconds"]
"""What an evaluation cost: simulator steps, simulated seconds (settling included) and wall
seconds (its batch's simulator call over the batch's robots); empty where not stored."""


def with_registered_traits(frame: pd.DataFrame) -> pd.DataFrame:
    """``frame`` (rows of the evaluations table with their ``descriptors``) with a column for
    each registered trait without a column of its own, read from ``descriptors`` (None where
    an evaluation has none), and without ``descriptors``."""
    frame = frame.copy()
    stored = frame["descriptors"] if "descriptors" in frame.columns else pd.Series([None] * len(frame))
    for name in traits.names():
        if name not in frame.columns:
            frame[name] = pd.array([(d or {}).get(name) if isinstance(d, dict) else None for d in stored],
                                   dtype="Float64")
    return frame.drop(columns=["descriptors"], errors="ignore")


def evaluation_rows(where) -> Select:
    """SELECT of one row per evaluation with the identity columns, the trait columns of the
    evaluations table and its ``descriptors`` (``with_registered_traits`` reads the other
    traits from them), filtered by ``where`` (a condition on the evaluations/individuals
    tables), ordered by run, generation and individual."""
    evaluations, individuals = EvaluationRow.__table__, IndividualRow.__table__
    return (
        select(
            individuals.c.id.label("individual_id"),
            evaluations.c.run_id,
            individuals.c.parent_id,
            evaluations.c.generation,
            individuals.c.generation_born,
            evaluations.c.age,
            evaluations.c.environment,
            *[evaluations.c[name] for name in traits.columns()],
            evaluations.c.stable,
            evaluations.c.error,
            evaluations.c.steps,
            evaluations.c.simulated_seconds,
            evaluations.c.seconds.label("wall_seconds"),
            evaluations.c.descriptors,
        )
        .join(individuals, evaluations.c.individual_id == individuals.c.id)
        .where(where)
        .order_by(evaluations.c.run_id, evaluations.c.generation, individuals.c.id)
    )


def individuals_frame(conn: Connection, run_ids: Sequence[int]) -> pd.DataFrame:
    """One row per evaluation, ordered by run, generation and individual."""
    return pd.concat(table_chunks(conn, "individuals", run_ids), ignore_index=True)


def populations_frame(conn: Connection, run_ids: Sequence[int]) -> pd.DataFrame:
    """Population membership with front rank (0 = non-dominated) per generation."""
    return pd.concat(table_chunks(conn, "populations", run_ids), ignore_index=True)


def _population_rows(run_ids: Sequence[int]) -> Select:
    members = PopulationMemberRow.__table__
    return (
        select(*[members.c[name] for name in POPULATION_COLUMNS])
        .where(members.c.run_id.in_(list(run_ids)))
        .order_by(members.c.run_id, members.c.generation, members.c.front_rank, members.c.individual_id)
    )


def table_chunks(
    conn: Connection, table: str, run_ids: Sequence[int], chunk_rows: int = CHUNK_ROWS
) -> Iterator[pd.DataFrame]:
    """Export table ``table`` (``TABLES``) of ``run_ids`` as frames of at most
    ``chunk_rows`` rows (``runs``: one frame), at least one (perhaps empty), each with the
    table's columns and the same types (nullable pandas types from the SQL columns)."""
    if table == "runs":
        yield runs_frame(conn, run_ids)
        return
    if table == "individuals":
        run_id = EvaluationRow.__table__.c.run_id
        query, columns = evaluation_rows(run_id.in_(list(run_ids))), individual_columns()
    elif table == "populations":
        query, columns = _population_rows(run_ids), POPULATION_COLUMNS
    else:
        raise UserError(f"unknown table {table!r}; choose {', '.join(TABLES)}")
    types = {column.name: _dtype(column.type) for column in query.selected_columns
             if column.name != "descriptors"}
    result = conn.execution_options(stream_results=True, yield_per=chunk_rows).execute(query)
    keys = list(result.keys())
    empty = True
    for rows in result.partitions():
        empty = False
        yield with_registered_traits(pd.DataFrame(rows, columns=keys).astype(types))[columns]
    if empty:
        yield with_registered_traits(pd.DataFrame(columns=keys).astype(types))[columns]


def _dtype(sql_type) -> str:
    """The pandas type of a column of SQL type ``sql_type``: nullable, so that a chunk with
    only missing values has the type of the others."""
    if isinstance(sql_type, Boolean):
        return "boolean"
    if isinstance(sql_type, Integer):
        return "Int64"
    if isinstance(sql_type, Float):
        return "float64"
    return "string"


def export_runs(engine: Engine, run_ids: Sequence[int], out_dir: str | Path, fmt: str = "csv") -> list[Path]:
    """Write runs, individuals and populations files for ``run_ids`` into ``out_dir``."""
    if fmt not in FORMATS:
        raise UserError(f"unknown format {fmt!r}; choose csv or parquet")
    if fmt == "parquet":
        require_pyarrow()
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(f"cannot create output directory {out}: {exc.strerror}") from exc
    with engine.connect() as conn:
        frames = {
            "runs": runs_frame(conn, run_ids),
            "individuals": individuals_frame(conn, run_ids),
            "populations": populations_frame(conn, run_ids),
        }
    return [_write(frame, out / f"{name}.{fmt}", fmt) for name, frame in frames.items()]


def _write(frame: pd.DataFrame, path: Path, fmt: str) -> Path:
    try:
        if fmt == "csv":
            frame.to_csv(path, index=False)
        else:
            frame.to_parquet(path, index=False)
    except OSError as exc:
        raise UserError(f"cannot write {path}: {exc.strerror}") from exc
    return path


def require_pyarrow() -> None:
    """UserError (how to install it) unless pyarrow, the Parquet writer, is installed."""
    try:
        import pyarrow  # noqa: F401  (a probe: is the optional Parquet writer installed?)
    except ImportError as exc:
        raise UserError("parquet export needs pyarrow: pip install pyarrow (or use --format csv)") from exc
