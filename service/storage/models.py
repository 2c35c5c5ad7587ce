"""SQLAlchemy 2 models: experiments, treatments, runs, individuals, evaluations, generations.

Ids are integers assigned by the database. An individual also keeps ``local_id``, the id the
evolutionary algorithm gave it inside its run; ``(run_id, local_id)`` is unique, so recording
the same generation twice inserts nothing new. ``parent_id`` points at the parent's database
id (NULL for a random newcomer, the root of a lineage).

Generation ``g`` of a run means: the individuals evaluated at ``g`` and the population kept
after selection at ``g`` (``population_members``). Generation 0 is the random initial
population.
"""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Any

from sqlalchemy import (
    JSON,
    Boolean,
    DateTime,
    Float,
    ForeignKey,
    Index,
    Integer,
    MetaData,
    String,
    Text,
    UniqueConstraint,
)
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column

from softevo.evolution import traits
from softevo.evolution.run_status import RunStatus

NAMING_CONVENTION = {
    "ix": "ix_%(column_0_label)s",
    "uq": "uq_%(table_name)s_%(column_0_N_name)s",
    "ck": "ck_%(table_name)s_%(constraint_name)s",
    "fk": "fk_%(table_name)s_%(column_0_name)s_%(referred_table_name)s",
    "pk": "pk_%(table_name)s",
}


def utcnow() -> datetime:
    """Timezone-aware current time (stored as UTC)."""
    return datetime.now(UTC)


class Base(DeclarativeBase):
    """Declarative base whose metadata carries the constraint naming convention."""

    metadata = MetaData(naming_convention=NAMING_CONVENTION)
    type_annotation_map = {dict[str, Any]: JSON, list[Any]: JSON}


# The per-evaluation fields stored in the ``evaluations`` table beside the individual.
EVALUATION_FIELDS = (
    "generation",
    "environment",
    "stiffness",
    "age",
    *traits.columns(),
    "descriptors",
    "objectives",
    "stable",
    "error",
    "seconds",
    "steps",
    "simulated_seconds",
)


class ExperimentRow(Base):
    """A named group of treatments (e.g. the paper's grid)."""

    __tablename__ = "experiments"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    name: Mapped[str] = mapped_column(String(200))
    preset: Mapped[str | None] = mapped_column(String(50))
    scale: Mapped[str | None] = mapped_column(String(20))
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)


class TreatmentRow(Base):
    """One treatment of an experiment; ``settings`` is ``evolution.treatments.Treatment`` as JSON."""

    __tablename__ = "treatments"
    __table_args__ = (UniqueConstraint("experiment_id", "name"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    experiment_id: Mapped[int] = mapped_column(ForeignKey("experiments.id", ondelete="CASCADE"))
    name: Mapped[str] = mapped_column(String(200))
    settings: Mapped[dict[str, Any]] = mapped_column(JSON)


class RunRow(Base):
    """One repetition (seed) of a treatment.

    ``generation`` is the last generation committed (-1 before generation 0);
    ``algorithm_state`` is the algorithm's JSON state after that generation, RNG included,
    from which the run resumes.
    """

    __tablename__ = "runs"
    __table_args__ = (UniqueConstraint("treatment_id", "repetition"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    treatment_id: Mapped[int] = mapped_column(ForeignKey("treatments.id", ondelete="CASCADE"))
    repetition: Mapped[int] = mapped_column(Integer)
    seed: Mapped[int] = mapped_column(Integer)
    status: Mapped[str] = mapped_column(String(20), default=RunStatus.PENDING.value, index=True)
    generation: Mapped[int] = mapped_column(Integer, default=-1)
    generations: Mapped[int] = mapped_column(Integer)
    algorithm_state: Mapped[dict[str, Any] | None] = mapped_column(JSON)
    error: Mapped[str | None] = mapped_column(Text)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    updated_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow, onupdate=utcnow)


class IndividualRow(Base):
    """Every individual that ever lived in a run (its genome never changes)."""

    __tablename__ = "individuals"
    __table_args__ = (UniqueConstraint("run_id", "local_id"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    run_id: Mapped[int] = mapped_column(ForeignKey("runs.id", ondelete="CASCADE"))
    local_id: Mapped[int] = mapped_column(Integer)
    parent_id: Mapped[int | None] = mapped_column(
        ForeignKey("individuals.id", ondelete="CASCADE"), index=True
    )
    generation_born: Mapped[int] = mapped_column(Integer)
    genome: Mapped[dict[str, Any]] = mapped_column(JSON)
    phenotype: Mapped[dict[str, Any] | None] = mapped_column(JSON)


class EvaluationRow(Base):
    """One evaluation of an individual: at birth, and again when the environment switches.

    ``objectives``: {name: value} of every objective the run selects on (its treatment's
    ``objectives``, ``evolution.selection.OBJECTIVES``), so a new objective needs no new
    column. The traits with columns of their own (``evolution.traits.column_traits()``: the
    paper's three objectives ``distance``, ``active_share`` and ``voxel_count``, and the
    shape descriptors) are columns, generated from their records (``add_trait_columns``);
    every other registered trait is read from ``descriptors``
    (``service.storage.trait_sql``). A failed or unstable evaluation keeps its ``error`` and
    the worst fitness.
    """

    __tablename__ = "evaluations"
    __table_args__ = (
        UniqueConstraint("individual_id", "generation", "environment"),
        Index("ix_evaluations_run_generation", "run_id", "generation"),
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    individual_id: Mapped[int] = mapped_column(ForeignKey("individuals.id", ondelete="CASCADE"))
    run_id: Mapped[int] = mapped_column(ForeignKey("runs.id", ondelete="CASCADE"))
    generation: Mapped[int] = mapped_column(Integer)
    age: Mapped[int] = mapped_column(Integer, default=0)
    environment: Mapped[str] = mapped_column(String(20))
    stiffness: Mapped[float] = mapped_column(Float)
    # a column per trait of ``evolution.traits.column_traits()`` (``add_trait_columns`` below)
    descriptors: Mapped[dict[str, Any] | None] = mapped_column(JSON)
    objectives: Mapped[dict[str, float] | None] = mapped_column(JSON)
    stable: Mapped[bool] = mapped_column(Boolean, default=True)
    error: Mapped[str | None] = mapped_column(Text)
    seconds: Mapped[float | None] = mapped_column(Float)  # wall seconds (the batch's mean)
    steps: Mapped[int | None] = mapped_column(Integer)  # simulator steps (None: stored before 0003)
    simulated_seconds: Mapped[float | None] = mapped_column(Float)


def add_trait_columns(row: type[Base]) -> None:
    """Give ``row`` a column per trait with one (``evolution.traits.column_traits()``), typed
    and nullable as its record says: the one place the trait columns are declared (the
    migrations create the same)."""
    for trait in traits.column_traits():
        kind = Integer if trait.integer else Float
        setattr(row, trait.name, mapped_column(kind, nullable=not trait.required))


add_trait_columns(EvaluationRow)


class GenerationRow(Base):
    """Summary of one committed generation of a run."""

    __tablename__ = "generations"

    run_id: Mapped[int] = mapped_column(ForeignKey("runs.id", ondelete="CASCADE"), primary_key=True)
    generation: Mapped[int] = mapped_column(Integer, primary_key=True)
    environment: Mapped[str] = mapped_column(String(20))
    evaluations: Mapped[int] = mapped_column(Integer)
    best_distance: Mapped[float] = mapped_column(Float)
    mean_distance: Mapped[float] = mapped_column(Float)
    front_size: Mapped[int] = mapped_column(Integer)
    stats: Mapped[dict[str, Any]] = mapped_column(JSON)
    evaluation_seconds: Mapped[float] = mapped_column(Float, default=0.0)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)


class PopulationMemberRow(Base):
    """Membership of the population kept at a generation, with its front rank (0 = Pareto)."""

    __tablename__ = "population_members"
    __table_args__ = (Index("ix_population_members_individual", "individual_id"),)

    run_id: Mapped[int] = mapped_column(ForeignKey("runs.id", ondelete="CASCADE"), primary_key=True)
    generation: Mapped[int] = mapped_column(Integer, primary_key=True)
    individual_id: Mapped[int] = mapped_column(
        ForeignKey("individuals.id", ondelete="CASCADE"), primary_key=True
    )
    front_rank: Mapped[int] = mapped_column(Integer)
    age: Mapped[int] = mapped_column(Integer, default=0)
