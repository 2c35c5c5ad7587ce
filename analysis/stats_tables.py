"""Statistics over DataFrames (paper section 2.5), built on ``evolution.stats``.

- The unit is the run: every test compares one value per run (its population's best
  distance at the generation, or its population's mean of a trait then), n = repetitions.
  Pooling the individuals of several runs would treat correlated samples as independent.
- Matched generations (``analysis.matching``): each comparison names its generation, the
  ``generation`` column. Static treatments are compared at the static treatments' common
  last generation, a transition against a static treatment at the last generation both
  have stored; start vs end is the first generation wholly in the treatment's final world
  (0; a transition's arrival) against its end generation: never a land start against a
  water end.
- Families (``analysis.matching.families``): each pair answers one question (stiffness
  within one world; a transition against the static control of its final world); the
  ``family`` column names it with the metric, ``family_size`` counts its tests, and
  Bonferroni (``p_bonferroni`` = min(1, p x family size)) runs within it. Cross-world pairs
  are described (means, medians), never tested. Start vs end: one family per metric across
  treatments.
- Tests follow the design. Runs of two treatments that share seeds start from the same
  generation-0 population: they are paired by seed and tested with the two-sided Wilcoxon
  signed-rank test on the seed-matched differences (runs without a partner left out).
  Treatments with seeds of their own (the presets, ``evolution.treatments``) are
  independent samples: two-sided Mann-Whitney U. Start vs end pairs each run with itself
  (signed-rank). The ``test`` column names the test.
- Intervals (``interval`` column): Student t intervals of the mean over runs
  (``t_interval``); of a difference, Welch's t for independent samples and the paired t for
  seed-matched runs. Their coverage at n = 7 was checked by simulation
  (``analysis.calibration``, docs/analysis.md); a percentile bootstrap covers about 90% at
  that n.
- Effect sizes: Vargha-Delaney ``A12`` = P(a > b) + P(a = b) / 2 over runs; for paired rows
  the share of seed-matched pairs with a above b (ties half). ``difference`` = mean_a -
  mean_b (the mean of the paired differences) with its 95% interval.
- ``detectable_A12``: the smallest A12 (above 0.5; its mirror alike) the test detects with
  80% power at the row's n and alpha / family size (normal model, ``analysis.power``); NaN
  when the exact-p floor makes every effect undetectable. A "no difference" reads with it.
- Descriptors over active robots: a robot with no active voxel moves nothing, so its
  frequency means nothing. ``frequency_active`` is the population mean over robots with an
  active voxel; ``passive_share`` the share of robots with none (flagged in the summary).
  Both frequencies are reported, the paper's choice being unclear, unless they are the
  same: a metric whose run values are constant or identical to another's is left out of
  the tables (``distinct_metrics``).
- The headline questions, one test each with Holm across them, are ``analysis.findings``;
  the pairwise tests here are secondary.

Which treatments are compared: those that differ in exactly one factor, environment
schedule or stiffness (``comparison_pairs``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pandas as pd
from scipy import stats

from softevo.analysis.data import ExperimentData
from softevo.analysis.matching import arrival_generation, comparison_pairs, families
from softevo.analysis.power import detectable_a12
from softevo.evolution import traits
from softevo.evolution.stats import bonferroni, mann_whitney, vargha_delaney

CONFIDENCE = 0.95
MAX_CURVE_POINTS = 500
ALPHA = 0.05
POWER = 0.8
INTERVAL = "Student t over runs (95%)"
MANN_WHITNEY = "Mann-Whitney U (independent seeds)"
SEED_PAIRED = "Wilcoxon signed-rank (seed-matched runs)"
RUN_PAIRED = "Wilcoxon signed-rank (the same runs)"
NOT_TESTED = "none (described)"
# Fewer runs than this in a group: no test, no interval, no "no pair differs" (issue 59.3: at
# n = 1 every p is 1, at n = 2 a 95% t band spans 0-17.5 around means of 3-5): the row says
# ``few_runs_text(n)`` and keeps the means.
MIN_TESTED_RUNS = 3


def few_runs_text(n: int) -> str:
    """What a comparison or interval of groups of ``n`` runs (< ``MIN_TESTED_RUNS``) says."""
    return f"n = {n}: not tested"


def is_untested(test: str) -> bool:
    """Whether a ``test`` column's value says that too few runs left the row untested."""
    return str(test).endswith(": not tested")
STAT_COLUMNS = [
    "comparison",
    "family",
    "family_size",
    "test",
    "metric",
    "unit",
    "a",
    "b",
    "generation",
    "start_generation",
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
    "A12",
    "detectable_A12",
    "difference",
    "difference_low",
    "difference_high",
    "interval",
]
DERIVED = ("frequency_active", "passive_share")
DERIVED_LABELS = {
    "frequency_active": "frequency, active robots (Hz)",
    "passive_share": "passive robots (share)",
}


def all_metrics() -> tuple[str, ...]:
    """The measures of a run the tables compare: best distance, every trait
    (``evolution.traits``, the registered ones included) and the derived ones."""
    return ("best_distance", *traits.names(), *DERIVED)


def metric_labels() -> dict[str, str]:
    """{metric: label} of ``all_metrics()``."""
    return {**traits.labels(), **DERIVED_LABELS}


def significance_mark(p: float, alpha: float = ALPHA) -> str:
    """``***`` (p < alpha/50), ``**`` (p < alpha/5), ``*`` (p < alpha) or ``ns``."""
    if not np.isfinite(p):
        return "n/a"
    for mark, limit in (("***", alpha / 50), ("**", alpha / 5), ("*", alpha)):
        if p < limit:
            return mark
    return "ns"


def t_interval(values: Sequence[float], confidence: float = CONFIDENCE) -> tuple[float, float, float]:
    """(mean, low, high): Student t interval of the mean, mean -+ t(n-1) sd / sqrt(n); NaN
    bounds for fewer than ``MIN_TESTED_RUNS`` values, a zero-width interval when they do not
    spread."""
    data = np.asarray(values, float)
    mean = float(data.mean()) if data.size else float("nan")
    if data.size < MIN_TESTED_RUNS:
        return mean, float("nan"), float("nan")
    half = stats.t.ppf((1 + confidence) / 2, data.size - 1) * data.std(ddof=1) / math.sqrt(data.size)
    return mean, float(mean - half), float(mean + half)


def welch_interval(a: Sequence[float], b: Sequence[float], confidence: float = CONFIDENCE):
    """(mean(a) - mean(b), low, high): Welch's t interval of a difference of means
    (Welch-Satterthwaite degrees of freedom); NaN bounds when a sample has fewer than
    ``MIN_TESTED_RUNS`` values."""
    x, y = np.asarray(a, float), np.asarray(b, float)
    difference = float(x.mean() - y.mean())
    if min(x.size, y.size) < MIN_TESTED_RUNS:
        return difference, float("nan"), float("nan")
    vx, vy = x.var(ddof=1) / x.size, y.var(ddof=1) / y.size
    if vx + vy == 0:
        return difference, difference, difference
    df = (vx + vy) ** 2 / (vx**2 / (x.size - 1) + vy**2 / (y.size - 1))
    half = stats.t.ppf((1 + confidence) / 2, df) * math.sqrt(vx + vy)
    return difference, difference - half, difference + half


# What a measure can be (inclusive): its intervals are clipped to this range, so that a
# distance's band never goes below 0 (a t interval of a few skewed values easily does).
MEASURE_RANGES: dict[str, tuple[float, float]] = {
    "best_distance": (0.0, math.inf),
    "distance": (0.0, math.inf),
    "active_share": (0.0, 1.0),
    "passive_share": (0.0, 1.0),
    "voxel_count": (0.0, math.inf),
    "frequency": (0.0, math.inf),
    "frequency_active": (0.0, math.inf),
    "qd_score": (0.0, math.inf),  # a MAP-Elites archive's (analysis.qd)
    "coverage": (0.0, 1.0),
}


def clipped(low: float, high: float, measure: str | None) -> tuple[float, float]:
    """(low, high) of an interval of ``measure`` clipped to ``MEASURE_RANGES``."""
    bottom, top = MEASURE_RANGES.get(measure or "", (-math.inf, math.inf))
    return min(max(low, bottom), top), max(min(high, top), bottom)


def ci_table(
    frame: pd.DataFrame, value: str, by: str | Sequence[str], confidence: float = CONFIDENCE
) -> pd.DataFrame:
    """Per group of ``by``: n, mean, low, high of column ``value`` (``t_interval``), the
    bounds clipped to what the measure allows (``clipped``: the measure is ``value``, or the
    group's ``metric`` where ``by`` holds one).

    Missing values are dropped; a group with no value gets NaN mean and bounds.
    """
    keys = [by] if isinstance(by, str) else list(by)
    rows = []
    for key, group in frame.groupby(keys, sort=False, dropna=False):
        values = group[value].dropna().to_numpy(dtype=float)
        mean, low, high = t_interval(values, confidence)
        labels = dict(zip(keys, key if isinstance(key, tuple) else (key,), strict=True))
        if np.isfinite(low):
            low, high = clipped(low, high, labels.get("metric", value))
        rows.append({**labels, "n": int(values.size), "mean": mean, "low": low, "high": high})
    return pd.DataFrame(rows, columns=[*keys, "n", "mean", "low", "high"])


def compare(a: Sequence[float], b: Sequence[float]) -> tuple[float, float]:
    """(U, two-sided p) of Mann-Whitney U; NaN for an empty sample."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    a, b = a[np.isfinite(a)], b[np.isfinite(b)]
    if a.size == 0 or b.size == 0:
        return float("nan"), float("nan")
    return mann_whitney(a, b)


def compare_paired(a: Sequence[float], b: Sequence[float]) -> tuple[float, float]:
    """(W, two-sided p) of the Wilcoxon signed-rank test on the differences a - b (pairs
    with a missing side left out; zero differences dropped, scipy's default); p = 1 when
    every difference is 0, NaN without a pair."""
    difference = np.asarray(a, float) - np.asarray(b, float)
    difference = difference[np.isfinite(difference)]
    if difference.size == 0:
        return float("nan"), float("nan")
    if not difference.any():
        return 0.0, 1.0
    result = stats.wilcoxon(difference)
    return float(result.statistic), float(result.pvalue)


def paired_a12(a: Sequence[float], b: Sequence[float]) -> float:
    """Share of pairs with a above b, ties counted half."""
    difference = np.asarray(a, float) - np.asarray(b, float)
    return float(((difference > 0).sum() + 0.5 * (difference == 0).sum()) / difference.size)


def adjust_families(table: pd.DataFrame, family: Sequence[str] = ("family",)) -> None:
    """Fill ``family_size``, ``p_bonferroni`` and ``significance`` in place, Bonferroni within
    each family (rows sharing the ``family`` columns; NaN p-values are not counted)."""
    table["p_bonferroni"] = np.nan
    table["family_size"] = 0
    for _, group in table.groupby(list(family), sort=False):
        valid = group["p"].notna()
        if valid.any():
            index = group.index[valid]
            table.loc[index, "p_bonferroni"] = bonferroni(group.loc[valid, "p"].to_numpy())
            table.loc[index, "family_size"] = int(valid.sum())
    table["significance"] = [significance_mark(p) for p in table["p_bonferroni"]]


def _matched(a: pd.Series, b: pd.Series) -> tuple[pd.Series, pd.Series]:
    """The values of ``a`` and ``b`` (indexed by seed) at the seeds both hold."""
    common = a.index.intersection(b.index)
    return a.loc[common], b.loc[common]


def _comparison_row(kind: str, question: str, metric: str, generation, names, a, b, design: str) -> dict:
    """One row; ``a`` and ``b`` are Series indexed by seed (paired designs match on it)."""
    a, b = pd.Series(a, dtype=float).dropna(), pd.Series(b, dtype=float).dropna()
    paired = design in (SEED_PAIRED, RUN_PAIRED)
    if paired:
        a, b = _matched(a, b)
    row = {"comparison": kind, "family": f"{question} | {metric}", "test": design, "metric": metric,
           "unit": "run", "a": names[0], "b": names[1], "generation": generation, "n_a": len(a),
           "n_b": len(b), "mean_a": a.mean(), "mean_b": b.mean(), "median_a": a.median(),
           "median_b": b.median()}  # fmt: skip
    tested = design != NOT_TESTED and len(a) and len(b)
    few = tested and min(len(a), len(b)) < MIN_TESTED_RUNS
    if not tested or few:  # too few runs: the effect described (A12, the difference), not tested
        a12 = (paired_a12(a.to_numpy(), b.to_numpy()) if paired else vargha_delaney(a, b)) if few else np.nan
        return {**row, "test": few_runs_text(min(len(a), len(b))) if few else design, "U": np.nan,
                "p": np.nan, "A12": a12, "detectable_A12": np.nan,
                "difference": a.mean() - b.mean() if few else np.nan, "difference_low": np.nan,
                "difference_high": np.nan, "interval": ""}  # fmt: skip
    if paired:
        u, p = compare_paired(a.to_numpy(), b.to_numpy())
        a12 = paired_a12(a.to_numpy(), b.to_numpy())
        difference, low, high = t_interval(a.to_numpy() - b.to_numpy())
        interval = "paired t (95%)"
    else:
        u, p = compare(a, b)
        a12 = vargha_delaney(a, b)
        difference, low, high = welch_interval(a, b)
        interval = "Welch t (95%)"
    return {**row, "U": u, "p": p, "A12": a12, "difference": difference, "difference_low": low,
            "difference_high": high, "interval": interval}  # fmt: skip


class _Values:
    """``ExperimentData.run_values`` per generation with ``DERIVED`` and each run's seed,
    each generation computed once."""

    def __init__(self, data: ExperimentData):
        self.data, self.cache = data, {}
        self.seeds = data.runs.set_index("run_id")["seed"]

    def frame(self, generation: int) -> pd.DataFrame:
        if generation not in self.cache:
            values = self.data.run_values(generation)
            derived = active_descriptors(self.data.populations_at(generation))
            values = values.merge(derived, on="run_id", how="left")
            values["seed"] = values["run_id"].map(self.seeds)
            self.cache[generation] = values
        return self.cache[generation]

    def __call__(self, generation: int | None, treatment: str, metric: str) -> pd.Series:
        """The treatment's run values of ``metric`` at ``generation``, indexed by seed."""
        if generation is None:
            return pd.Series(dtype=float)
        values = self.frame(generation)
        chosen = values[values["treatment"] == treatment]
        return pd.Series(chosen[metric].to_numpy(float), index=chosen["seed"].to_numpy())


def active_descriptors(members: pd.DataFrame) -> pd.DataFrame:
    """Per run (run_id): ``frequency_active``, the mean frequency over its members with an
    active voxel (NaN when none has one), and ``passive_share``, the share with none."""
    active = members["active_share"] > 0
    frequency = members["frequency"].where(active)
    grouped = pd.DataFrame({"run_id": members["run_id"], "f": frequency, "passive": ~active}).groupby(
        "run_id"
    )
    return pd.DataFrame(
        {"frequency_active": grouped["f"].mean(), "passive_share": grouped["passive"].mean().astype(float)}
    ).reset_index()


def design_of(data: ExperimentData, a: str, b: str) -> str:
    """``SEED_PAIRED`` when runs of treatments ``a`` and ``b`` share seeds, else
    ``MANN_WHITNEY``."""
    seeds = data.runs.groupby("treatment")["seed"].agg(set)
    return SEED_PAIRED if seeds.get(a, set()) & seeds.get(b, set()) else MANN_WHITNEY


def best_distance_per_run(data: ExperimentData) -> pd.DataFrame:
    """Per run: treatment, repetition, generation and best_distance at its treatment's
    display generation (``analysis.matching``)."""
    values = data.display_run_values()
    return values[["run_id", "treatment", "repetition", "generation", "best_distance"]]


def treatment_comparisons(data: ExperimentData, metrics: Sequence[str] | None = None) -> pd.DataFrame:
    """Every treatment pair (``analysis.matching.families``) at its generation, per metric
    (default: ``distinct_metrics``): tested within its family by the design's test, or
    described (cross-world)."""
    metrics = distinct_metrics(data) if metrics is None else metrics
    values = _Values(data)
    rows = []
    for metric in metrics:
        for pair in families(data.treatments):
            generation = data.pair_generation(pair.a, pair.b)
            design = design_of(data, pair.a, pair.b) if pair.tested else NOT_TESTED
            kind = "between treatments" if pair.tested else "described"
            a, b = values(generation, pair.a, metric), values(generation, pair.b, metric)
            rows.append(
                _comparison_row(kind, pair.question, metric, generation, (pair.a, pair.b), a, b, design)
            )
    return _finish(rows)


def start_end_comparisons(data: ExperimentData, metrics: Sequence[str] | None = None) -> pd.DataFrame:
    """Each metric (default ``distinct_metrics``, best distance among them: the evolved
    gain) between the start (a) and the treatment's end generation (b, named in
    ``generation``) over its runs, each run paired with itself (signed-rank); one family per
    metric across treatments. The start is the first generation wholly in the world the
    treatment ends in (``start_generation``: 0, or a transition's arrival), so that start
    and end are measured in one world."""
    metrics = distinct_metrics(data) if metrics is None else metrics
    values = _Values(data)
    rows = []
    for metric in metrics:
        for _, treatment in data.treatments.iterrows():
            name, start = treatment["name"], arrival_generation(treatment)
            end = data.end_generation(name)
            names = (f"{name} start", f"{name} end")
            a, b = values(start, name, metric), values(end, name, metric)
            row = _comparison_row("start vs end", "start vs end", metric, end, names, a, b, RUN_PAIRED)
            rows.append(row | {"start_generation": start})
    return _finish(rows)


def distinct_metrics(data: ExperimentData, metrics: Sequence[str] | None = None) -> tuple[str, ...]:
    """``metrics`` less those whose run values (at generation 0 and at every generation a
    treatment is shown or compared at) are constant, or identical to an earlier metric's
    (e.g. ``frequency_active`` when every robot has an active voxel, ``passive_share`` when
    it is always 0): they would repeat another metric's tests or test nothing."""
    metrics = all_metrics() if metrics is None else metrics
    values = _Values(data)
    generations = sorted({0, *(g for _, g in shown_generations(data))})
    frames = [values.frame(g) for g in generations]
    kept, seen = [], []
    for metric in metrics:
        vector = np.concatenate([f[metric].to_numpy(float) for f in frames]) if frames else np.array([])
        finite = vector[np.isfinite(vector)]
        if finite.size == 0 or finite.min() == finite.max():
            continue
        if any(np.array_equal(vector, other, equal_nan=True) for other in seen):
            continue
        kept.append(metric)
        seen.append(vector)
    return tuple(kept)


def _finish(rows: list[dict]) -> pd.DataFrame:
    table = pd.DataFrame(
        rows, columns=[c for c in STAT_COLUMNS if c not in ("p_bonferroni", "significance", "family_size")]
    )
    for column in ("generation", "start_generation"):
        table[column] = table[column].astype("Int64")
    adjust_families(table)
    table["detectable_A12"] = [
        _detectable(r.test, r.n_a, r.n_b, r.family_size) for r in table.itertuples(index=False)
    ]
    return table[STAT_COLUMNS]


def _detectable(test: str, n_a: int, n_b: int, family_size: int) -> float:
    if test == NOT_TESTED or is_untested(test) or family_size < 1 or min(n_a, n_b) < MIN_TESTED_RUNS:
        return float("nan")
    return detectable_a12(int(n_a), int(n_b), ALPHA / family_size, POWER, test != MANN_WHITNEY)


def statistics_table(data: ExperimentData) -> pd.DataFrame:
    """All rows of the report: between treatments (tested and described), then start vs end."""
    return pd.concat([treatment_comparisons(data), start_end_comparisons(data)], ignore_index=True)


def shown_generations(data: ExperimentData) -> list[tuple[str, int]]:
    """(treatment, generation) for each treatment at its display generation and at every
    generation it is compared at with another treatment, in treatment order."""
    found: dict[str, set[int]] = {name: set() for name in data.treatment_names}
    for name in data.treatment_names:
        found[name].add(data.display_generation(name))
    for a, b in comparison_pairs(data.treatments):
        generation = data.pair_generation(a, b)
        found[a].add(generation)
        found[b].add(generation)
    return [
        (name, g) for name in data.treatment_names for g in sorted(x for x in found[name] if x is not None)
    ]


def summary_table(data: ExperimentData) -> pd.DataFrame:
    """Per metric (``distinct_metrics``), treatment and generation (``shown_generations``):
    repetitions, mean and
    t interval over runs of the run values (best distance, a population mean of a trait,
    ``frequency_active``, or ``passive_share``: the share of robots without an active
    voxel)."""
    values = _Values(data)
    # every metric constant (one run of one generation, e.g. a run failed at generation 0):
    # the primary measure alone, so that the summary still shows it
    metrics = distinct_metrics(data) or all_metrics()[:1]
    parts = []
    for name, generation in shown_generations(data):
        for metric in metrics:
            series = values(generation, name, metric).reset_index(drop=True)
            parts.append(
                pd.DataFrame({"metric": metric, "treatment": name, "generation": generation, "value": series})
            )
            if series.empty:  # keep the row: a group with no value gets NaN
                parts[-1] = pd.DataFrame(
                    {"metric": [metric], "treatment": [name], "generation": [generation], "value": [np.nan]}
                )
    frame = pd.concat(parts, ignore_index=True)
    table = ci_table(frame, "value", ["metric", "treatment", "generation"])
    order = {name: k for k, name in enumerate(data.treatment_names)}
    metric_order = {m: k for k, m in enumerate(all_metrics())}
    table["generation"] = table["generation"].astype("Int64")
    table = table.sort_values(
        ["metric", "treatment", "generation"],
        key=lambda col: (
            col.map(metric_order)
            if col.name == "metric"
            else (col.map(order) if col.name == "treatment" else col)
        ),
        kind="stable",
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


def fitness_curves(data: ExperimentData, max_points: int = MAX_CURVE_POINTS) -> pd.DataFrame:
    """Per treatment and generation: mean best distance over repetitions with its t
    interval (columns treatment, generation, environment, n, mean, low, high; a generation
    whose runs were evaluated in different worlds has a row per world). Long runs are thinned
    to about ``max_points`` generations (``plotted_generations``)."""
    frame = data.generations
    switches = [int(s) for s in data.treatments["switch_at"].dropna()]
    kept = plotted_generations(frame["generation"].to_numpy(), switches, max_points)
    frame = frame[frame["generation"].isin(kept)]
    return ci_table(frame, "best_distance", ["treatment", "generation", "environment"])
