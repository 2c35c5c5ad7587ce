"""Which treatments are compared, and at which generation (SPEC.md section 4: treatments are
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
- Start vs end: generation 0 against the treatment's *end generation*, the last one all its
  runs have stored.
- A treatment is shown (its summary row, its box in the descriptor figure, its Pareto
  front) at its *display generation*: the static generation for a static treatment, its
  end generation for a transition.

Runs that have stored nothing yet (generation -1) are left out; a generation is None when no
run of the treatments has stored any.
"""

from __future__ import annotations

from collections.abc import Iterable
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


def static_names(treatments: pd.DataFrame) -> list[str]:
    """Names of the treatments that stay in one environment."""
    return list(treatments.loc[treatments["switch_at"].isna(), "name"])


def last_common_generation(runs: pd.DataFrame, names: Iterable[str]) -> int | None:
    """The last generation every started run of the treatments ``names`` has stored."""
    started = runs[runs["treatment"].isin(list(names)) & (runs["generation"] >= 0)]
    return None if started.empty else int(started["generation"].min())


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


def analysis_generations(treatments: pd.DataFrame, runs: pd.DataFrame) -> list[int]:
    """Every generation an analysis compares or shows: 0, each pair's, each end and display
    generation (sorted, without None)."""
    found = {0}
    for a, b in comparison_pairs(treatments):
        found.add(pair_generation(treatments, runs, a, b))
    for name in treatments["name"]:
        found.add(end_generation(runs, name))
        found.add(display_generation(treatments, runs, name))
    return sorted(g for g in found if g is not None)
