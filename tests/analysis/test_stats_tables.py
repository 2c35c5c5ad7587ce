"""Statistics over DataFrames: checked against scipy and hand-made cases."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest
from scipy import stats as scipy_stats

from softevo.analysis.calibration import interval_coverage
from softevo.analysis.matching import DESCRIBED, families, family_size
from softevo.analysis.stats_tables import (
    MANN_WHITNEY,
    SEED_PAIRED,
    active_descriptors,
    adjust_families,
    ci_table,
    compare,
    compare_paired,
    comparison_pairs,
    design_of,
    paired_a12,
    significance_mark,
    welch_interval,
)
from softevo.evolution.treatments import paper_grid, preset_scale


def test_ci_table_is_the_t_interval_per_group():
    rng = np.random.default_rng(0)
    frame = pd.DataFrame(
        {"treatment": ["a"] * 7 + ["b"] * 7, "value": np.r_[rng.normal(5, 1, 7), rng.normal(9, 2, 7)]}
    )
    table = ci_table(frame, "value", "treatment")
    assert list(table["treatment"]) == ["a", "b"]
    for row in table.itertuples():
        values = frame.loc[frame["treatment"] == row.treatment, "value"].to_numpy()
        low, high = scipy_stats.t.interval(0.95, 6, loc=values.mean(), scale=scipy_stats.sem(values))
        assert (row.n, row.mean, row.low, row.high) == pytest.approx((7, values.mean(), low, high))


def test_ci_table_single_value_and_missing_values():
    frame = pd.DataFrame({"g": ["a", "b", "b"], "v": [2.0, np.nan, np.nan]})
    table = ci_table(frame, "v", "g").set_index("g")
    assert (table.loc["a", "n"], table.loc["a", "mean"]) == (1, 2.0) and np.isnan(table.loc["a", "low"])
    assert table.loc["b", "n"] == 0 and np.isnan(table.loc["b", "mean"])


def test_ci_table_clips_an_interval_to_what_the_measure_allows():
    """A distance is never negative, a share lies in [0, 1]: the t interval of a few skewed
    values is clipped there (the unclipped one here runs below 0; issue 49.4)."""
    frame = pd.DataFrame(
        {"metric": ["distance"] * 3 + ["active_share"] * 3 + ["symmetry"] * 3,
         "value": [0.1, 0.2, 5.0, 0.0, 0.05, 0.99, 0.1, 0.2, 5.0]}
    )  # fmt: skip
    by_metric = ci_table(frame, "value", "metric").set_index("metric")
    assert by_metric.loc["distance", "low"] == 0.0 and by_metric.loc["distance", "high"] > 5.0
    assert (by_metric.loc["active_share", "low"], by_metric.loc["active_share", "high"]) == (0.0, 1.0)
    assert by_metric.loc["symmetry", "low"] < 0  # no known range: the t interval as it is
    distances = frame[frame["metric"] == "distance"].rename(columns={"value": "best_distance"})
    assert ci_table(distances, "best_distance", "metric")["low"].tolist() == [0.0]


def test_welch_interval_matches_scipy():
    a, b = [1.1, 2.3, 2.9, 4.0, 5.2, 3.3, 2.0], [3.4, 6.1, 7.7, 8.0, 9.5, 10.2, 4.4]
    reference = scipy_stats.ttest_ind(a, b, equal_var=False).confidence_interval(0.95)
    assert welch_interval(a, b)[1:] == pytest.approx((reference.low, reference.high))


@pytest.mark.parametrize(("distribution", "low", "high"), [("normal", 0.93, 0.97), ("uniform", 0.92, 0.97)])
def test_the_t_interval_covers_95_percent_at_n_7_and_the_percentile_bootstrap_does_not(
    distribution, low, high
):
    assert low <= interval_coverage("t", distribution, 7, 1500) <= high
    assert interval_coverage("percentile bootstrap", distribution, 7, 400) < 0.93


@pytest.mark.parametrize("distribution", ["normal", "uniform"])
def test_the_t_interval_covers_95_percent_at_the_study_scale(distribution):
    n = preset_scale("study").repetitions  # the n docs/results publishes
    assert 0.93 <= interval_coverage("t", distribution, n, 1500) <= 0.97


def test_the_paired_test_is_wilcoxon_on_the_differences():
    a, b = np.array([3.0, 5.0, 2.0, 8.0, 7.0, 9.0, 4.0]), np.array([1.0, 4.5, 2.5, 5.0, 3.0, 8.0, 1.0])
    reference = scipy_stats.wilcoxon(a - b)
    assert compare_paired(a, b) == pytest.approx((reference.statistic, reference.pvalue))
    assert compare_paired([1.0, 2.0], [1.0, 2.0]) == (0.0, 1.0)
    assert paired_a12(a, b) == pytest.approx(6 / 7)


def _grid(treatments):
    return pd.DataFrame(
        [{"name": t.name, "environment": t.environment, "stiffness_mpa": t.stiffness_mpa} for t in treatments]
    )


def test_families_on_the_paper_grid():
    from collections import Counter

    found = families(_grid(paper_grid()))
    sizes = Counter(pair.question for pair in found)
    assert sizes == {
        "stiffness in land": 10,
        "stiffness in water": 10,
        "land-water S3 vs its final world": 1,
        "water-land S3 vs its final world": 1,
        DESCRIBED: 8,  # land vs water at 5 stiffnesses, each transition vs its first world, the two
    }
    described = {(p.a, p.b) for p in found if not p.tested}
    assert ("land S1", "water S1") in described and ("land S3", "land-water S3") in described
    assert ("land-water S3", "water-land S3") in described
    assert family_size(_grid(paper_grid()), "stiffness in water") == 10


def test_the_test_follows_the_seeds():
    shared = pd.DataFrame({"treatment": ["x", "x", "y", "y"], "seed": [0, 1, 0, 1]})
    own = pd.DataFrame({"treatment": ["x", "x", "y", "y"], "seed": [0, 1, 1000, 1001]})
    assert design_of(SimpleNamespace(runs=shared), "x", "y") == SEED_PAIRED
    assert design_of(SimpleNamespace(runs=own), "x", "y") == MANN_WHITNEY
    # the presets give every treatment seeds of its own: Mann-Whitney between them
    grid = paper_grid("study")
    runs = pd.DataFrame(
        [{"treatment": t.name, "seed": t.seed_of(r)} for t in grid for r in range(t.repetitions)]
    )
    assert {design_of(SimpleNamespace(runs=runs), a, b) for a, b in comparison_pairs(_grid(grid))} == {
        MANN_WHITNEY
    }


def test_frequency_over_active_robots_and_passive_robots_flagged():
    members = pd.DataFrame(
        {
            "run_id": [1, 1, 1, 2, 2],
            "active_share": [0.0, 0.5, 0.2, 0.0, 0.0],
            "frequency": [9.0, 2.0, 4.0, 1.0, 3.0],
        }
    )
    derived = active_descriptors(members).set_index("run_id")
    assert derived.loc[1, "frequency_active"] == pytest.approx(3.0)  # not 5.0 with the passive one
    assert derived.loc[1, "passive_share"] == pytest.approx(1 / 3)
    assert np.isnan(derived.loc[2, "frequency_active"]) and derived.loc[2, "passive_share"] == 1.0


def test_compare_matches_scipy_on_known_samples():
    a = [1.1, 2.3, 2.9, 4.0, 5.2, 3.3]
    b = [3.4, 6.1, 7.7, 8.0, 9.5, 10.2, 4.4]
    reference = scipy_stats.mannwhitneyu(a, b, alternative="two-sided")
    assert compare(a, b) == pytest.approx((reference.statistic, reference.pvalue))


def test_identical_samples_give_p_one_and_a_clear_shift_a_small_p():
    same = [0.2, 0.5, 0.9, 1.4, 2.0]
    assert compare(same, same)[1] == pytest.approx(1.0)
    assert compare([0.0] * 5, [0.0] * 5)[1] == pytest.approx(1.0)
    low, high = np.arange(10.0), np.arange(10.0) + 100.0
    u, p = compare(low, high)
    assert u == 0.0 and p < 1e-3


def test_compare_ignores_missing_values_and_reports_empty_samples_as_nan():
    assert compare([1.0, np.nan, 2.0], [5.0, 6.0])[0] == 0.0
    assert all(np.isnan(compare([], [1.0, 2.0])))


def test_bonferroni_within_families_multiplies_and_caps_at_one():
    table = pd.DataFrame(
        {
            "comparison": ["x", "x", "x", "x", "y"],
            "metric": ["m", "m", "m", "n", "m"],
            "p": [0.01, 0.02, 0.5, 0.01, 0.04],
        }
    )
    adjust_families(table, ("comparison", "metric"))
    assert table["p_bonferroni"].tolist() == pytest.approx([0.03, 0.06, 1.0, 0.01, 0.04])
    assert table["family_size"].tolist() == [3, 3, 3, 1, 1]
    assert table["significance"].tolist() == ["*", "ns", "ns", "*", "*"]


def test_bonferroni_leaves_missing_p_values_out_of_the_count():
    table = pd.DataFrame({"family": ["x | m"] * 3, "p": [0.01, np.nan, 0.2]})
    adjust_families(table)
    assert table["p_bonferroni"].iloc[0] == pytest.approx(0.02)
    assert np.isnan(table["p_bonferroni"].iloc[1])
    assert table["significance"].iloc[1] == "n/a"


@pytest.mark.parametrize(
    ("p", "mark"), [(0.0009, "***"), (0.001, "**"), (0.009, "**"), (0.049, "*"), (0.05, "ns"), (1.0, "ns")]
)
def test_significance_marks(p, mark):
    assert significance_mark(p) == mark


def test_comparison_pairs_on_the_paper_grid():
    grid = pd.DataFrame(
        [
            {"name": t.name, "environment": t.environment, "stiffness_mpa": t.stiffness_mpa}
            for t in paper_grid()
        ]
    )
    pairs = comparison_pairs(grid)
    # 10 stiffness pairs per static environment, land vs water at 5 stiffnesses, and among
    # the four S3 treatments the 5 pairs other than land S3 vs water S3 (already counted)
    assert len(pairs) == 10 + 10 + 5 + 5
    assert ("land S1", "land S5") in pairs and ("land S2", "water S2") in pairs
    assert ("land S3", "land-water S3") in pairs and ("water S3", "water-land S3") in pairs
    assert ("land-water S3", "water-land S3") in pairs
    assert ("land S1", "water S2") not in pairs and ("land S1", "land-water S3") not in pairs


def test_long_curves_are_thinned_but_keep_both_ends_and_the_switch():
    from softevo.analysis.stats_tables import plotted_generations

    assert plotted_generations(np.arange(10), [5], 20).tolist() == list(range(10))
    kept = plotted_generations(np.arange(9000), [4500], 100)
    assert 100 <= len(kept) <= 102
    assert {0, 4499, 4500, 8999} <= set(kept.tolist())


def test_fewer_than_three_runs_get_no_interval():
    """Issue 59.3: at n = 2 a 95% t band spanned 0-17.5 around means of 3-5."""
    from softevo.analysis.stats_tables import MIN_TESTED_RUNS, few_runs_text, t_interval, welch_interval

    assert MIN_TESTED_RUNS == 3 and few_runs_text(2) == "n = 2: not tested"
    mean, low, high = t_interval([3.0, 5.0])
    assert mean == 4.0 and np.isnan(low) and np.isnan(high)
    assert all(np.isfinite(t_interval([3.0, 5.0, 4.0])))
    difference, low, high = welch_interval([3.0, 5.0], [1.0, 2.0, 3.0])
    assert difference == 2.0 and np.isnan(low) and np.isnan(high)
