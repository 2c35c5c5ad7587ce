"""Statistics over DataFrames (paper section 2.5), built on ``evolution.stats``.

- Confidence intervals: percentile bootstrap 95% intervals of the mean over repetitions
  (one value per run: its best distance, or its final population's mean of a trait).
- Mann-Whitney U (two-sided) between treatments, and between the start (generation 0) and
  the end (last generation) of a treatment.
- Bonferroni: p-values are multiplied by the number of comparisons in their family and
  capped at 1. A family is one metric of one kind of comparison: e.g. the "symmetry"
  comparisons between treatments form one family, the start-vs-end comparisons of
  "symmetry" another.

Which treatments are compared: those that differ in exactly one factor, environment
schedule or stiffness (``comparison_pairs``). On the paper's grid that is every stiffness
pair within an environment, land against water at each stiffness, and every pair among the
four S3 treatments (each transition against its static controls).

Samples: between treatments and start vs end, a descriptor is compared over the pooled
individuals of the final (or initial) populations of all repetitions (unit "individual");
the best distance is compared over runs (unit "run").
"""

from __future__ import annotations

from collections.abc import Sequence
from itertools import combinations

import numpy as np
import pandas as pd

from softevo.analysis.data import TRAITS, ExperimentData
from softevo.evolution.stats import bonferroni, bootstrap_ci, mann_whitney

CONFIDENCE = 0.95
N_RESAMPLES = 10_000
CURVE_RESAMPLES = 2_000  # per generation of the fitness curves
MAX_CURVE_POINTS = 500
ALPHA = 0.05
STAT_COLUMNS = [
    "comparison",
    "metric",
    "unit",
    "a",
    "b",
    "n_a",
    "n_b",
    "mean_a",
    "mean_b",
    "median_a",
    "median_b",
    "U",
    "p",
    "p_bonferroni",
    "significance",
]


def significance_mark(p: float, alpha: float = ALPHA) -> str:
    """``***`` (p < alpha/50), ``**`` (p < alpha/5), ``*`` (p < alpha) or ``ns``."""
    if not np.isfinite(p):
        return "n/a"
    for mark, limit in (("***", alpha / 50), ("**", alpha / 5), ("*", alpha)):
        if p < limit:
            return mark
    return "ns"


def ci_table(
    frame: pd.DataFrame,
    value: str,
    by: str | Sequence[str],
    rng: np.random.Generator,
    confidence: float = CONFIDENCE,
    n_resamples: int = N_RESAMPLES,
) -> pd.DataFrame:
    """Per group of ``by``: n, mean, low, high of column ``value`` (bootstrap CI of the mean).

    Missing values are dropped; a group with no value gets NaN mean and bounds.
    """
    keys = [by] if isinstance(by, str) else list(by)
    rows = []
    for key, group in frame.groupby(keys, sort=False, dropna=False):
        values = group[value].dropna().to_numpy(dtype=float)
        if values.size:
            mean, low, high = bootstrap_ci(values, rng, confidence, n_resamples)
        else:
            mean = low = high = float("nan")
        key = key if isinstance(key, tuple) else (key,)
        rows.append(
            {
                **dict(zip(keys, key, strict=True)),
                "n": int(values.size),
                "mean": mean,
                "low": low,
                "high": high,
            }
        )
    return pd.DataFrame(rows, columns=[*keys, "n", "mean", "low", "high"])


def compare(a: Sequence[float], b: Sequence[float]) -> tuple[float, float]:
    """(U, two-sided p) of Mann-Whitney U; NaN for an empty sample."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    a, b = a[np.isfinite(a)], b[np.isfinite(b)]
    if a.size == 0 or b.size == 0:
        return float("nan"), float("nan")
    return mann_whitney(a, b)


def adjust_families(table: pd.DataFrame, family: Sequence[str] = ("comparison", "metric")) -> None:
    """Fill ``p_bonferroni`` and ``significance`` in place, Bonferroni within each family
    (rows sharing the ``family`` columns; NaN p-values are not counted)."""
    table["p_bonferroni"] = np.nan
    for _, group in table.groupby(list(family), sort=False):
        valid = group["p"].notna()
        if valid.any():
            index = group.index[valid]
            table.loc[index, "p_bonferroni"] = bonferroni(group.loc[valid, "p"].to_numpy())
    table["significance"] = [significance_mark(p) for p in table["p_bonferroni"]]


def comparison_pairs(treatments: pd.DataFrame) -> list[tuple[str, str]]:
    """Pairs of treatment names that differ in exactly one of environment and stiffness."""
    rows = list(treatments[["name", "environment", "stiffness_mpa"]].itertuples(index=False))
    return [
        (a.name, b.name)
        for a, b in combinations(rows, 2)
        if (a.environment == b.environment) != bool(np.isclose(a.stiffness_mpa, b.stiffness_mpa))
    ]


def _comparison_row(kind: str, metric: str, unit: str, names, a, b) -> dict:
    a = pd.Series(a, dtype=float).dropna()
    b = pd.Series(b, dtype=float).dropna()
    u, p = compare(a, b)
    return {
        "comparison": kind,
        "metric": metric,
        "unit": unit,
        "a": names[0],
        "b": names[1],
        "n_a": len(a),
        "n_b": len(b),
        "mean_a": a.mean(),
        "mean_b": b.mean(),
        "median_a": a.median(),
        "median_b": b.median(),
        "U": u,
        "p": p,
    }


def best_distance_per_run(data: ExperimentData) -> pd.DataFrame:
    """Per run: treatment, repetition and best_distance of its last stored generation."""
    generations = data.generations
    last = generations.groupby("run_id")["generation"].transform("max")
    final = generations[generations["generation"] == last]
    return final[["run_id", "treatment", "repetition", "best_distance"]].reset_index(drop=True)


def treatment_comparisons(data: ExperimentData, metrics: Sequence[str] = TRAITS) -> pd.DataFrame:
    """Mann-Whitney U between treatment pairs (``comparison_pairs``): best distance over runs,
    each trait over the final populations' individuals; Bonferroni per metric."""
    pairs = comparison_pairs(data.treatments)
    best = best_distance_per_run(data)
    final = data.final_populations()
    rows = []
    for a, b in pairs:
        rows.append(
            _comparison_row(
                "between treatments",
                "best_distance",
                "run",
                (a, b),
                best.loc[best["treatment"] == a, "best_distance"],
                best.loc[best["treatment"] == b, "best_distance"],
            )
        )
    for metric in metrics:
        for a, b in pairs:
            rows.append(
                _comparison_row(
                    "between treatments",
                    metric,
                    "individual",
                    (a, b),
                    final.loc[final["treatment"] == a, metric],
                    final.loc[final["treatment"] == b, metric],
                )
            )
    return _finish(rows)


def start_end_comparisons(data: ExperimentData, metrics: Sequence[str] = TRAITS) -> pd.DataFrame:
    """Mann-Whitney U of each trait between the initial and the final populations of each
    treatment (a = start, b = end); Bonferroni per metric across treatments."""
    start, end = data.initial_populations(), data.final_populations()
    rows = [
        _comparison_row(
            "start vs end",
            metric,
            "individual",
            (f"{name} start", f"{name} end"),
            start.loc[start["treatment"] == name, metric],
            end.loc[end["treatment"] == name, metric],
        )
        for metric in metrics
        for name in data.treatment_names
    ]
    return _finish(rows)


def _finish(rows: list[dict]) -> pd.DataFrame:
    table = pd.DataFrame(rows, columns=STAT_COLUMNS[:-2])
    adjust_families(table)
    return table[STAT_COLUMNS]


def statistics_table(data: ExperimentData) -> pd.DataFrame:
    """All tests of the report: between treatments, then start vs end."""
    return pd.concat([treatment_comparisons(data), start_end_comparisons(data)], ignore_index=True)


def summary_table(data: ExperimentData, rng: np.random.Generator) -> pd.DataFrame:
    """Per treatment and metric: repetitions, mean and bootstrap CI over runs.

    The value of a run is its final best distance (``best_distance``) or its final
    population's mean of a trait.
    """
    best = best_distance_per_run(data).rename(columns={"best_distance": "value"})
    best["metric"] = "best_distance"
    final = data.final_populations()
    per_run = final.groupby(["treatment", "run_id"], sort=False)[list(TRAITS)].mean()
    per_run = per_run.reset_index().melt(
        id_vars=["treatment", "run_id"], var_name="metric", value_name="value"
    )
    values = pd.concat([best[["treatment", "run_id", "metric", "value"]], per_run])
    table = ci_table(values, "value", ["metric", "treatment"], rng)
    order = {name: k for k, name in enumerate(data.treatment_names)}
    metric_order = {m: k for k, m in enumerate(["best_distance", *TRAITS])}
    table = table.sort_values(
        ["metric", "treatment"],
        key=lambda col: col.map(metric_order if col.name == "metric" else order),
    )
    return table.reset_index(drop=True)


def plotted_generations(generations: np.ndarray, switches: Sequence[int], max_points: int) -> np.ndarray:
    """At most about ``max_points`` generations spread evenly from first to last, plus the
    generations on either side of each environment switch (so the jump stays sharp)."""
    generations = np.unique(generations)
    if len(generations) <= max_points:
        return generations
    spread = generations[np.unique(np.linspace(0, len(generations) - 1, max_points).round().astype(int))]
    near_switch = [g for s in switches for g in (s - 1, s)]
    return np.intersect1d(generations, np.union1d(spread, near_switch))


def fitness_curves(
    data: ExperimentData, rng: np.random.Generator, max_points: int = MAX_CURVE_POINTS
) -> pd.DataFrame:
    """Per treatment and generation: mean best distance over repetitions with its bootstrap
    CI (columns treatment, generation, n, mean, low, high). Long runs are thinned to about
    ``max_points`` generations (``plotted_generations``)."""
    frame = data.generations
    switches = [int(s) for s in data.treatments["switch_at"].dropna()]
    kept = plotted_generations(frame["generation"].to_numpy(), switches, max_points)
    frame = frame[frame["generation"].isin(kept)]
    return ci_table(frame, "best_distance", ["treatment", "generation"], rng, n_resamples=CURVE_RESAMPLES)
