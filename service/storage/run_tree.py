"""A run's phylogeny: every individual with its parent, birth, last generation kept and birth
evaluation (``run_phylogeny``, paged), and a bounded drawing of it (``tree_sample``).

A node's environment and traits are those of its first evaluation (the one that selected
it into the run, in the world it was born into): every trait of ``evolution.traits`` in a
page of ``run_phylogeny``, the paper's three objectives (``NODE_OBJECTIVES``) in
``tree_sample``; ``last_generation`` is the last generation whose kept population held it
(None if selection dropped it at once).
``tree_sample`` picks in SQL what the dashboard draws: the surviving lineages (every
ancestor of the final population, newest first, at most ``max_survivors``) and a
deterministic sample of at most ``extinct`` individuals that were kept once but left no
descendant in the final population, so a 30 x 9000-generation run stays a few thousand
nodes in the browser.
"""

from __future__ import annotations

from typing import Any

from sqlalchemy import Connection, and_, func, select

from softevo.errors import UserError
from softevo.evolution import traits
from softevo.evolution.treatments import Treatment
from softevo.service.storage.models import (
    EvaluationRow,
    IndividualRow,
    PopulationMemberRow,
    RunRow,
    TreatmentRow,
)
from softevo.service.storage.rows import columns as columns_of
from softevo.service.storage.rows import dict_rows
from softevo.service.storage.trait_sql import trait_values

NODE_OBJECTIVES = ("distance", "active_share", "voxel_count")
BIRTH = ("individual_id", "generation", "environment")  # where and when an evaluation was
SAMPLE_PRIME = 10_007  # the extinct sample orders ids by (id * SAMPLE_STEP) mod this prime
SAMPLE_STEP = 7_919
ID_CHUNK = 500  # ids bound per IN (...) when reading the chosen nodes


def birth_evaluations(run_id: int, names: tuple[str, ...] = NODE_OBJECTIVES):
    """Subquery: each individual of run ``run_id`` with its first evaluation's
    generation, environment and the traits ``names`` (any registered trait)."""
    ev = EvaluationRow.__table__
    ranked = (
        select(
            *columns_of(ev, *BIRTH),
            *trait_values(names),
            func.row_number().over(partition_by=ev.c.individual_id, order_by=ev.c.generation).label("n"),
        )
        .where(ev.c.run_id == run_id)
        .subquery("ranked")
    )
    return select(*columns_of(ranked, *BIRTH, *names)).where(ranked.c.n == 1).subquery("birth")


def last_kept(run_id: int, generation: int | None = None):
    """Subquery: individual_id, last_generation (the last kept population holding it, at or
    before ``generation`` if given)."""
    pm = PopulationMemberRow.__table__
    query = select(pm.c.individual_id, func.max(pm.c.generation).label("last_generation")).where(
        pm.c.run_id == run_id
    )
    if generation is not None:
        query = query.where(pm.c.generation <= generation)
    return query.group_by(pm.c.individual_id).subquery("last_kept")


def run_facts(conn: Connection, run_id: int) -> dict[str, Any]:
    """The run's last stored generation, its treatment and where its environment switches:
    {run_id, generation, generations, treatment (``evolution.treatments.Treatment``),
    switch_at, arrival (first generation wholly in the new world), environments}.
    UserError for an unknown run."""
    runs, treatments = RunRow.__table__, TreatmentRow.__table__
    row = conn.execute(
        select(runs.c.generation, runs.c.generations, treatments.c.settings)
        .join(treatments, runs.c.treatment_id == treatments.c.id)
        .where(runs.c.id == run_id)
    ).first()
    if row is None:
        raise UserError(f"no run {run_id}")
    treatment = Treatment.from_settings(row.settings)
    return {
        "run_id": run_id,
        "generation": int(row.generation),
        "generations": int(row.generations),
        "treatment": treatment,
        "switch_at": treatment.switch_generation(),
        "switch_over": treatment.switch_over,
        "arrival": treatment.arrival_generation(),
        "environments": treatment.environment.split("-"),
    }


def _node_query(
    run_id: int,
    generation: int | None = None,
    parent_generation: bool = False,
    ids: list[int] | None = None,
    names: tuple[str, ...] = NODE_OBJECTIVES,
):
    """SELECT of the nodes of run ``run_id`` (born at or before ``generation`` if given),
    each with the traits ``names`` of its birth evaluation.

    Birth evaluation and last generation kept are looked up per individual (correlated,
    through the indexes on ``evaluations (individual_id, ...)`` and
    ``population_members.individual_id``), so a page or a sample of a large run costs only
    its own rows. ``ids``: only those individuals (of this run)."""
    ind, ev, pm = IndividualRow.__table__, EvaluationRow.__table__, PopulationMemberRow.__table__
    earlier = ev.alias("earlier")
    first = (
        select(func.min(earlier.c.generation)).where(earlier.c.individual_id == ind.c.id).scalar_subquery()
    )
    kept = select(func.max(pm.c.generation)).where(pm.c.individual_id == ind.c.id)  # one run's anyway
    if generation is not None:
        kept = kept.where(pm.c.generation <= generation)
    joined = ind.outerjoin(ev, and_(ev.c.individual_id == ind.c.id, ev.c.generation == first))
    columns = [
        ind.c.id,
        ind.c.parent_id,
        ind.c.generation_born,
        kept.scalar_subquery().label("last_generation"),
        ev.c.environment,
        *trait_values(names, ev),
    ]
    if parent_generation:
        parent = ind.alias("parent")
        joined = joined.outerjoin(parent, parent.c.id == ind.c.parent_id)
        columns.append(parent.c.generation_born.label("parent_generation"))
    query = select(*columns).select_from(joined)
    # chosen ids: looked up by primary key (they are of this run), else the run's index
    query = query.where(ind.c.id.in_(ids)) if ids is not None else query.where(ind.c.run_id == run_id)
    if generation is not None:
        query = query.where(ind.c.generation_born <= generation)
    return query


def run_phylogeny(
    conn: Connection,
    run_id: int,
    generation: int | None = None,
    limit: int | None = None,
    offset: int = 0,
) -> tuple[int, list[dict[str, Any]]]:
    """(total, rows): the individuals of run ``run_id`` in id order (born at or before
    ``generation`` if given: the tree as it stood then), ``limit`` rows from ``offset``.
    Row keys: id, parent_id, generation_born, last_generation, environment and every trait
    (``evolution.traits.names()``). UserError for an unknown run."""
    run_facts(conn, run_id)
    ind = IndividualRow.__table__
    chosen = select(ind.c.id).where(ind.c.run_id == run_id)
    if generation is not None:
        chosen = chosen.where(ind.c.generation_born <= generation)
    total = conn.execute(select(func.count()).select_from(chosen.subquery())).scalar_one()
    page = chosen.order_by(ind.c.id).offset(offset)
    if limit is not None:
        page = page.limit(limit)
    ids = list(conn.execute(page).scalars())
    rows = []
    for start in range(0, len(ids), ID_CHUNK):
        chunk = ids[start : start + ID_CHUNK]
        query = _node_query(run_id, generation, ids=chunk, names=traits.names()).order_by(ind.c.id)
        rows += dict_rows(conn, query)
    return int(total), rows


def surviving_ancestry(run_id: int, generation: int):
    """Recursive CTE (id, parent_id): the members of the population kept at ``generation``
    and all their ancestors, each once (UNION, not UNION ALL)."""
    ind, pm = IndividualRow.__table__, PopulationMemberRow.__table__
    anchor = (
        select(ind.c.id, ind.c.parent_id)
        .join(pm, pm.c.individual_id == ind.c.id)
        .where(pm.c.run_id == run_id, pm.c.generation == generation)
    )
    cte = anchor.cte("surviving", recursive=True)
    step = select(ind.c.id, ind.c.parent_id).join(cte, ind.c.id == cte.c.parent_id)
    return cte.union(step)


def tree_sample(
    conn: Connection, run_id: int, max_survivors: int = 4000, extinct: int = 400
) -> dict[str, Any]:
    """What the dashboard's tree draws (module doc): {run_id, generation (the last stored),
    switch_at, switch_over, arrival, environments, survivors_total, extinct_total, nodes};
    each node has id, parent_id, generation_born, last_generation, environment, the
    ``NODE_OBJECTIVES``, parent_generation (the parent's birth)
    and surviving (in, or an ancestor of, the final population)."""
    facts = run_facts(conn, run_id)
    last = facts["generation"]
    keys = ("run_id", "generation", "switch_at", "switch_over", "arrival", "environments")
    out = {key: facts[key] for key in keys}
    if last < 0:
        return {**out, "survivors_total": 0, "extinct_total": 0, "nodes": []}
    ind, pm = IndividualRow.__table__, PopulationMemberRow.__table__
    surviving = surviving_ancestry(run_id, last)
    survivor_ids = (
        select(surviving.c.id, ind.c.generation_born)
        .join(ind, ind.c.id == surviving.c.id)
        .order_by(ind.c.generation_born.desc(), ind.c.id)
        .limit(max_survivors)
    )
    shown_survivors = [row.id for row in conn.execute(survivor_ids)]
    alive = select(surviving.c.id)
    kept = select(pm.c.individual_id.label("id")).where(pm.c.run_id == run_id).distinct().subquery("kept")
    extinct_ids = (
        select(kept.c.id)
        .where(kept.c.id.not_in(alive))
        .order_by((kept.c.id * SAMPLE_STEP) % SAMPLE_PRIME, kept.c.id)
        .limit(extinct)
    )
    shown_extinct = [row.id for row in conn.execute(extinct_ids)]
    rows = []
    for ids, flag in ((shown_survivors, True), (shown_extinct, False)):
        for chunk in range(0, len(ids), ID_CHUNK):
            part = ids[chunk : chunk + ID_CHUNK]
            nodes = _node_query(run_id, parent_generation=True, ids=part)
            rows += [{**row, "surviving": flag} for row in dict_rows(conn, nodes)]
    rows.sort(key=lambda row: row["id"])
    survivors_total = conn.execute(select(func.count()).select_from(surviving)).scalar_one()
    kept_total = conn.execute(select(func.count()).select_from(kept)).scalar_one()
    kept_survivors = conn.execute(select(func.count()).where(kept.c.id.in_(alive))).scalar_one()
    return {
        **out,
        "survivors_total": int(survivors_total),
        "extinct_total": int(kept_total - kept_survivors),
        "nodes": rows,
    }
