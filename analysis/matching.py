"""Which treatments are compared, and at which generation (docs/spec.md section 4: treatments are
compared at the same generation). Functions of the ``treatments`` and ``runs`` frames of
``analysis.data`` (the loader calls them before it reads the populations).

- Pairs (``comparison_pairs``): treatments that differ in exactly one factor, environment
  schedule or stiffness. On the paper's grid that is every stiffness pair within an
  environment, land against water at each stiffness, and every pair among the four S3
  treatments (each transition against its static controls).
- Static treatments (one environment) are compared with each other at the *static
  generation*: the last generation that every run of every static treatment has stored.
  On the paper's grid that is 5000 (the last index 4999), although its static S3 runs go on
  to 9000.
- A pair with a transition treatment is compared at the last generation that every run of
  both treatments has stored (the paper: 9000, a transition against the static S3 runs).
- Start vs end: the first generation wholly in the treatment's final world (0; a
  transition's *arrival*, ``arrival_generation``) against the treatment's *end generation*,
  the last one all its runs have stored.
- A treatment is shown (its summary row, its box in the descriptor figure, its Pareto
  front) at its *display generation*: the static generation for a static treatment, its
  end generation for a transition.

Runs that have stored nothing yet (generation -1) are left out; a generation is None when no
run of the treatments has stored any.

Families (``families``), the one place that says which question each pair answers and which
pairs are tested together (a Bonferroni family is one question and one metric):

- ``stiffness in W``: treatments of one environment schedule W that differ in stiffness
  (on the paper's grid 10 pairs per world: 5 stiffness levels);
- ``T vs its final world``: a transition T against the static treatment of the world it ends
  in, at its stiffness (land-water S3 vs water S3, water-land S3 vs land S3), a family of one
  per transition;
- every other pair (land against water at a stiffness, a transition against its first
  world, the two transitions against each other) compares distances or traits measured in
  different worlds, whose absolute difference comes from arbitrary parameter choices: it is
  described (means, medians), never tested (``DESCRIBED``).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from itertools import combinations

import numpy as np
import pandas as pd


def comparison_pairs(treatments: pd.DataFrame) -> list[tuple[str, str]]:
    """Pairs of treatment names that differ in exactly one of environment and stiffness."""
    rows = list(treatments[["name", "environment", "stiffness_mpa"]].itertuples(index=False))
    return [
        (a.name, b.name)
        for a, b in combinations(rows, 2)
        if (a.environment == b.environment) != bool(np.isclose(a.stiffness_mpa, b.stiffness_mpa))
    ]


DESCRIBED = "cross-world (described, not tested)"


@dataclass(frozen=True)
class Pair:
    """Treatments ``a`` and ``b`` and the question (family) they answer; ``tested`` is False
    for a cross-world pair (``DESCRIBED``)."""

    a: str
    b: str
    question: str

    @property
    def tested(self) -> bool:
        return self.question != DESCRIBED


def final_world(environment: str) -> str:
    """The world a schedule ends in: ``land-water`` -> ``water``; ``land`` -> ``land``."""
    return environment.split("-")[-1]


def question_of(a, b) -> str:
    """The family of the pair of treatment rows ``a`` and ``b`` (name, environment,
    stiffness_mpa) that differ in exactly one factor (see the module doc)."""
    if a.environment == b.environment:
        return f"stiffness in {a.environment}"
    for transition, static in ((a, b), (b, a)):
        if "-" in transition.environment and static.environment == final_world(transition.environment):
            return f"{transition.name} vs its final world"
    return DESCRIBED


def families(treatments: pd.DataFrame) -> list[Pair]:
    """Every pair of ``comparison_pairs`` with its question (family), in the same order."""
    rows = {r.name: r for r in treatments[["name", "environment", "stiffness_mpa"]].itertuples(index=False)}
    return [Pair(a, b, question_of(rows[a], rows[b])) for a, b in comparison_pairs(treatments)]


def family_size(treatments: pd.DataFrame, question: str) -> int:
    """How many tested pairs the question ``question`` holds for these treatments."""
    return sum(1 for pair in families(treatments) if pair.tested and pair.question == question)


def static_names(treatments: pd.DataFrame) -> list[str]:
    """Names of the treatments that stay in one environment."""
    return list(treatments.loc[treatments["switch_at"].isna(), "name"])


def last_common_generation(runs: pd.DataFrame, names: Iterable[str]) -> int | None:
    """The last generation every finished run of the treatments ``names`` has stored (every
    started run's, while none has finished). A run that stopped earlier (cancelled, failed,
    or still running behind the finished ones) is left out there (``left_out_runs``), so
    that one run cancelled at generation 0 does not pull the comparison back to 0."""
    started = runs[runs["treatment"].isin(list(names)) & (runs["generation"] >= 0)]
    if "status" in started.columns and (started["status"] == "finished").any():
        started = started[started["status"] == "finished"]
    return None if started.empty else int(started["generation"].min())


def left_out_runs(treatments: pd.DataFrame, runs: pd.DataFrame) -> pd.DataFrame:
    """The runs (rows of ``runs``) that have not stored the generation their treatment is
    shown at (``display_generation``): they are missing from its summary and tests."""
    shown = {name: display_generation(treatments, runs, name) for name in treatments["name"]}
    behind = [
        shown.get(row.treatment) is not None and row.generation < shown[row.treatment]
        for row in runs[["treatment", "generation"]].itertuples(index=False)
    ]
    return runs[np.array(behind, dtype=bool)] if len(runs) else runs


def left_out_note(treatments: pd.DataFrame, runs: pd.DataFrame) -> str | None:
    """One sentence naming the runs ``left_out_runs`` leaves out, or None for none."""
    left = left_out_runs(treatments, runs)
    if left.empty:
        return None
    named = ", ".join(
        f"r{int(row.run_id)} ({row.treatment}, {row.status} after generation {int(row.generation)})"
        if row.generation >= 0 else f"r{int(row.run_id)} ({row.treatment}, {row.status}, nothing stored)"
        for row in left.itertuples(index=False)
    )
    return (f"{len(left)} run(s) stopped before the generation their treatment is compared at (the last "
            f"one its finished runs share) and are left out of the summary and the tests: {named}")


def static_generation(treatments: pd.DataFrame, runs: pd.DataFrame) -> int | None:
    """The generation the static treatments are compared at."""
    return last_common_generation(runs, static_names(treatments))


def pair_generation(treatments: pd.DataFrame, runs: pd.DataFrame, a: str, b: str) -> int | None:
    """The generation treatments ``a`` and ``b`` are compared at."""
    static = set(static_names(treatments))
    if a in static and b in static:
        return static_generation(treatments, runs)
    return last_common_generation(runs, (a, b))


def end_generation(runs: pd.DataFrame, name: str) -> int | None:
    """The last generation every started run of treatment ``name`` has stored."""
    return last_common_generation(runs, (name,))


def display_generation(treatments: pd.DataFrame, runs: pd.DataFrame, name: str) -> int | None:
    """The generation treatment ``name`` is shown at."""
    if name in static_names(treatments):
        return static_generation(treatments, runs)
    return end_generation(runs, name)


def arrival_generation(treatment: pd.Series) -> int:
    """The first generation wholly in the treatment's final world (a row of ``treatments``):
    0 for a static treatment, switch_at + switch_over for a transition."""
    if pd.isna(treatment.get("switch_at")):
        return 0
    return int(treatment["switch_at"]) + int(treatment.get("switch_over", 0) or 0)


def analysis_generations(treatments: pd.DataFrame, runs: pd.DataFrame) -> list[int]:
    """Every generation an analysis compares or shows: 0, each transition's arrival in its
    final world, each pair's, each end and display generation (sorted, without None)."""
    found = {0, *(arrival_generation(row) for _, row in treatments.iterrows())}
    for a, b in comparison_pairs(treatments):
        found.add(pair_generation(treatments, runs, a, b))
    for name in treatments["name"]:
        found.add(end_generation(runs, name))
        found.add(display_generation(treatments, runs, name))
    return sorted(g for g in found if g is not None)
