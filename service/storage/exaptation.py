"""Exaptation across an environment transition: which founders' lines survive, and what
their traits did on the way (``exaptation``).

Definitions (``docs/sql.md`` gives the same as SQL):

- the *founders* are the population kept at ``switch_at - 1``, the last generation wholly
  in the first world (the population that was moved);
- the *final population* is the one kept at the run's last stored generation; a *line* is a
  (founder, final member) pair where the founder is an ancestor of (or is) the final member;
  a founder *survives* when it has at least one line; ``front_lines`` counts its lines whose
  final member is on the final Pareto front (front rank 0);
- every final member's ancestry is followed to its *root*, the newcomer (``parent_id``
  NULL) its line started from; ``from_founders`` counts the final members with a founder
  among their ancestors (the others descend from newcomers that arrived after the switch);
- along each line, a trait's value at the *founder*, at the *switch* (the newest ancestor
  kept at ``arrival``, the first generation wholly in the new world; ``switch_at`` for an
  abrupt switch) and at the *end* (the final member) are those of each individual's first
  evaluation, and ``first_changed`` is the birth generation of the first individual after
  the founder along the line whose value differs from the founder's (None: never changed).

The traits followed are every trait of the registry with ``along_lines``
(``evolution.traits.along_lines()``, read when called): the built-in ones from their columns, a
registered one from each evaluation's ``descriptors``.
"""

from __future__ import annotations

from typing import Any

import pandas as pd
from sqlalchemy import Connection, select

from softevo.errors import UserError
from softevo.evolution import traits
from softevo.service.storage.models import PopulationMemberRow
from softevo.service.storage.phylogeny import population_lines
from softevo.service.storage.rows import finite
from softevo.service.storage.run_tree import birth_evaluations, run_facts


def _members(conn: Connection, run_id: int, generation: int) -> pd.DataFrame:
    pm = PopulationMemberRow.__table__
    rows = conn.execute(
        select(pm.c.individual_id, pm.c.front_rank)
        .where(pm.c.run_id == run_id, pm.c.generation == generation)
        .order_by(pm.c.individual_id)
    ).all()
    return pd.DataFrame(rows, columns=["individual_id", "front_rank"])


def final_ancestry(conn: Connection, run_id: int, generation: int) -> pd.DataFrame:
    """Every member of the population kept at ``generation`` with each of its ancestors:
    final_id, id, parent_id, generation_born, depth (0 = the member), newest first."""
    cte = population_lines(run_id, generation, "final_id", down=False)
    result = conn.execute(select(cte).order_by(cte.c.final_id, cte.c.depth))
    return pd.DataFrame(result.fetchall(), columns=list(result.keys()))


def _birth_traits(conn: Connection, run_id: int, followed: tuple[str, ...]) -> dict[int, dict[str, Any]]:
    """{individual id: {trait: value at its first evaluation}} of run ``run_id``."""
    birth = birth_evaluations(run_id, followed)
    rows = conn.execute(select(birth)).mappings()
    return {int(row["individual_id"]): {name: row[name] for name in followed} for row in rows}


def exaptation(conn: Connection, run_id: int, limit: int | None = None, offset: int = 0) -> dict[str, Any]:
    """The exaptation summary of a transition run (module doc): {run_id, switch_at,
    switch_over, arrival, generation (the last stored), environments, founders (count),
    founders_surviving, final_population, from_founders, roots (distinct root newcomers of
    the final population), every_line_rooted (each final member's ancestry ends at a
    newcomer), founder_lines ([{founder_id, lines, front_lines, traits (at its birth)}] for
    every founder),
    lines_total, lines (``limit`` of them from ``offset``, ordered by founder then final
    member: {founder_id, individual_id, root_id, traits: {trait: {founder, switch, end,
    first_changed}}})}. UserError for an unknown run or one without a transition."""
    facts = run_facts(conn, run_id)
    switch_at, last = facts["switch_at"], facts["generation"]
    if switch_at is None:
        raise UserError(f"run {run_id} has no environment transition")
    founders = _members(conn, run_id, switch_at - 1)
    final = _members(conn, run_id, last)
    ancestry = final_ancestry(conn, run_id, last)
    arrival_ids = (
        set(_members(conn, run_id, facts["arrival"])["individual_id"]) if last >= facts["arrival"] else set()
    )
    founder_ids = set(founders["individual_id"])
    front = set(final.loc[final["front_rank"] == 0, "individual_id"])
    followed = traits.along_lines()
    at_birth = _birth_traits(conn, run_id, followed)
    lines, roots, rooted = [], {}, True
    for final_id, path in ancestry.groupby("final_id", sort=True):
        path = path.sort_values("depth")
        top = path.iloc[-1]
        rooted = rooted and pd.isna(top["parent_id"])
        roots[int(final_id)] = int(top["id"])
        ids = [int(i) for i in path["id"]]
        born = [int(g) for g in path["generation_born"]]
        for position, ancestor in enumerate(ids):
            if ancestor in founder_ids:
                lines.append(
                    _line(
                        ancestor,
                        int(final_id),
                        roots[int(final_id)],
                        ids,
                        born,
                        position,
                        arrival_ids,
                        at_birth,
                        followed,
                    )
                )
    lines.sort(key=lambda line: (line["founder_id"], line["individual_id"]))
    per_founder = {int(f): [0, 0] for f in founders["individual_id"]}
    for line in lines:
        per_founder[line["founder_id"]][0] += 1
        per_founder[line["founder_id"]][1] += line["individual_id"] in front
    with_founder = {line["individual_id"] for line in lines}
    end = None if limit is None else offset + limit
    return finite(
        {
            **{
                key: facts[key]
                for key in ("run_id", "switch_at", "switch_over", "arrival", "generation", "environments")
            },
            "founders": len(founder_ids),
            "founders_surviving": sum(1 for count, _ in per_founder.values() if count),
            "final_population": len(final),
            "from_founders": len(with_founder),
            "roots": sorted(set(roots.values())),
            "every_line_rooted": bool(rooted),
            "founder_lines": [
                {"founder_id": f, "lines": count, "front_lines": on_front, "traits": at_birth.get(f, {})}
                for f, (count, on_front) in sorted(per_founder.items())
            ],
            "lines_total": len(lines),
            "lines": lines[offset:end],
        }
    )


def _line(founder, final_id, root_id, ids, born, position, arrival_ids, at_birth, followed) -> dict[str, Any]:
    """One line: ``ids[0]`` is the final member, ``ids[position]`` the founder; ``at_birth``
    holds each individual's traits, ``followed`` names those the line reports."""
    forward = list(range(position, -1, -1))  # founder .. final member
    at_switch = next((ids[k] for k in reversed(forward) if ids[k] in arrival_ids), None)
    values = {}
    for trait in followed:
        start = at_birth.get(founder, {}).get(trait)
        changed = next(
            (born[k] for k in forward[1:] if at_birth.get(ids[k], {}).get(trait) != start),
            None,
        )
        values[trait] = {
            "founder": start,
            "switch": None if at_switch is None else at_birth.get(at_switch, {}).get(trait),
            "end": at_birth.get(final_id, {}).get(trait),
            "first_changed": changed,
        }
    return {
        "founder_id": founder,
        "individual_id": final_id,
        "root_id": root_id,
        "switch_id": at_switch,
        "traits": values,
    }
