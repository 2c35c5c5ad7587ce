"""Statistics over DataFrames: checked against scipy and hand-made cases."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy import stats as scipy_stats

from softevo.analysis.stats_tables import (
    adjust_families,
    ci_table,
    compare,
    comparison_pairs,
    significance_mark,
)
from softevo.service.treatments import paper_grid


def test_ci_table_matches_scipy_bootstrap_per_group():
    rng = np.random.default_rng(0)
    frame = pd.DataFrame(
        {"treatment": ["a"] * 30 + ["b"] * 30, "value": np.r_[rng.normal(5, 1, 30), rng.normal(9, 2, 30)]}
    )
    table = ci_table(frame, "value", "treatment", np.random.default_rng(1), n_resamples=20_000)
    assert list(table["treatment"]) == ["a", "b"]
    for row in table.itertuples():
        values = frame.loc[frame["treatment"] == row.treatment, "value"].to_numpy()
        reference = scipy_stats.bootstrap(
            (values,), np.mean, method="percentile", n_resamples=20_000, rng=np.random.default_rng(2)
        ).confidence_interval
        assert row.n == 30
        assert row.mean == pytest.approx(values.mean())
        assert row.low == pytest.approx(reference.low, abs=0.05 * values.std())
        assert row.high == pytest.approx(reference.high, abs=0.05 * values.std())


def test_ci_table_single_value_and_missing_values():
    frame = pd.DataFrame({"g": ["a", "b", "b"], "v": [2.0, np.nan, np.nan]})
    table = ci_table(frame, "v", "g", np.random.default_rng(0)).set_index("g")
    assert tuple(table.loc["a", ["n", "mean", "low", "high"]]) == (1, 2.0, 2.0, 2.0)
    assert table.loc["b", "n"] == 0 and np.isnan(table.loc["b", "mean"])


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
    adjust_families(table)
    assert table["p_bonferroni"].tolist() == pytest.approx([0.03, 0.06, 1.0, 0.01, 0.04])
    assert table["significance"].tolist() == ["*", "ns", "ns", "*", "*"]


def test_bonferroni_leaves_missing_p_values_out_of_the_count():
    table = pd.DataFrame({"comparison": ["x"] * 3, "metric": ["m"] * 3, "p": [0.01, np.nan, 0.2]})
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
