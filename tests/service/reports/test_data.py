"""Reading a real tiny experiment back (``service.reports.data.load_experiment``), and the
statistics tables over it."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy import stats as scipy_stats

from softevo.analysis.stats_tables import (
    RUN_PAIRED,
    SEED_PAIRED,
    all_metrics,
    best_distance_per_run,
    distinct_metrics,
    fitness_curves,
    statistics_table,
    summary_table,
)
from softevo.errors import UserError
from softevo.evolution.traits import names as trait_names
from softevo.service.reports.data import load_experiment
from softevo.service.storage.experiments import resolve_experiment


def test_the_experiment_is_read_back(tiny, tiny_data):
    data = tiny_data
    assert data.experiment["name"] == "tiny-analysis"
    assert data.treatment_names == ["land S3", "water-land S3"]
    assert data.treatments["switch_at"].tolist()[1] == 2 and data.treatments["switch_at"].isna()[0]
    assert sorted(data.runs["run_id"]) == sorted(tiny.run_ids)
    assert (data.runs["status"] == "finished").all()
    assert len(data.generations) == 6 * 3
    counts = data.populations.groupby(["run_id", "generation"]).size()
    assert (counts == 4).all() and len(counts) == 6 * 2  # only the two ends of each run
    assert sorted(data.populations["generation"].unique()) == [0, 2]
    assert set(data.evaluations["individual_id"]) == set(data.populations["individual_id"])


def test_members_carry_the_traits_of_their_latest_evaluation(tiny_data):
    members = tiny_data.populations
    assert members[list(trait_names())].notna().all().all()
    assert (members["evaluation_generation"] <= members["generation"]).all()
    transition = members[members["treatment"] == "water-land S3"]
    expected = np.where(transition["generation"] >= 2, "land", "water")
    assert (transition["environment"].to_numpy() == expected).all()
    static = members[members["treatment"] == "land S3"]
    assert (static["environment"] == "land").all()


def test_initial_and_final_populations(tiny_data):
    assert (tiny_data.initial_populations()["generation"] == 0).all()
    final = tiny_data.final_populations()
    assert len(final) == 4 * 6 and (final["generation"] == 2).all()


def test_resolve_experiment_by_id_and_name(tiny):
    with tiny.engine.connect() as conn:
        for reference in (str(tiny.experiment_id), f"e{tiny.experiment_id}", "tiny-analysis", "latest"):
            assert resolve_experiment(conn, reference) == tiny.experiment_id
        with pytest.raises(UserError, match="no experiment 'e999'"):
            resolve_experiment(conn, "e999")
        with pytest.raises(UserError, match="no experiment 'nope'"):
            resolve_experiment(conn, "nope")


def test_load_unknown_experiment_is_a_user_error(tiny):
    with pytest.raises(UserError, match="no experiment e999"):
        load_experiment(tiny.engine, 999)


def test_statistics_table_on_the_real_experiment(tiny_data):
    table = statistics_table(tiny_data)
    between = table[table["comparison"] == "between treatments"]
    metrics = distinct_metrics(tiny_data)  # METRICS less the constant or repeated ones
    assert set(metrics) <= set(all_metrics()) and "voxel_count" in metrics
    assert sorted(between["metric"]) == sorted(metrics)
    assert (between["a"] == "land S3").all() and (between["b"] == "water-land S3").all()
    assert (between["family"] == [f"water-land S3 vs its final world | {m}" for m in between["metric"]]).all()
    start_end = table[table["comparison"] == "start vs end"]
    assert len(start_end) == 2 * len(metrics)
    assert (start_end["test"] == RUN_PAIRED).all()
    # one family of two comparisons per metric: adjusted = min(1, 2 p)
    tested = start_end.dropna(subset=["p"])
    assert tested["p_bonferroni"].to_numpy() == pytest.approx(np.minimum(1, 2 * tested["p"]))
    assert (table["unit"] == "run").all() and (table["generation"] == 2).all()
    # both treatments run seeds 0, 1 and 2: their runs are paired by seed
    assert (between["test"] == SEED_PAIRED).all()
    final = tiny_data.final_populations()
    per_run = final.groupby(["treatment", "repetition"])["voxel_count"].mean()  # one value per run
    row = between[between["metric"] == "voxel_count"].iloc[0]
    differences = per_run["land S3"].to_numpy() - per_run["water-land S3"].to_numpy()
    if differences.any():
        reference = scipy_stats.wilcoxon(differences)
        assert (row["U"], row["p"]) == pytest.approx((reference.statistic, reference.pvalue))
    assert (row["n_a"], row["n_b"]) == (3, 3)
    assert row["difference"] == pytest.approx(differences.mean())
    assert row["difference_low"] <= row["difference"] <= row["difference_high"]
    assert row["family_size"] == 1 and row["p_bonferroni"] == pytest.approx(row["p"])
    assert np.isnan(row["detectable_A12"])  # 3 pairs: the signed-rank floor is 0.25
    again = statistics_table(tiny_data)  # the same table again
    pd.testing.assert_frame_equal(table, again)


def test_summary_and_fitness_curves_are_over_repetitions(tiny_data):
    summary = summary_table(tiny_data)
    assert (summary["n"] == 3).all()
    assert (summary["low"] <= summary["mean"] + 1e-12).all()
    assert (summary["mean"] <= summary["high"] + 1e-12).all()
    best = best_distance_per_run(tiny_data)
    row = summary[(summary["metric"] == "best_distance") & (summary["treatment"] == "land S3")]
    assert row["mean"].iloc[0] == pytest.approx(
        best.loc[best["treatment"] == "land S3", "best_distance"].mean()
    )
    curves = fitness_curves(tiny_data)
    assert len(curves) == 2 * 3 and (curves["n"] == 3).all()
    generations = tiny_data.generations
    mean = generations.groupby(["treatment", "generation"])["best_distance"].mean()
    for r in curves.itertuples():
        assert r.mean == pytest.approx(mean[(r.treatment, r.generation)])
