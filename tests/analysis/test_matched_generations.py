"""Comparisons at matched generations, on a hand-built database where the static S3 runs
outlive the others (tests/analysis/matched.py): stiffness comparisons at the static
treatments' common last generation, transitions against static S3 at their own."""

from __future__ import annotations

import numpy as np
import pytest

from softevo.analysis.stats_tables import (
    distinct_metrics,
    start_end_comparisons,
    statistics_table,
    summary_table,
    treatment_comparisons,
)
from softevo.service.reports.data import load_experiment
from softevo.service.storage import open_database
from tests.analysis import matched


@pytest.fixture(scope="module")
def hand(tmp_path_factory):
    engine = open_database(f"sqlite:///{tmp_path_factory.mktemp('matched') / 'matched.db'}")
    experiment_id = matched.build(engine)
    yield engine, experiment_id
    engine.dispose()


@pytest.fixture(scope="module")
def data(hand):
    return load_experiment(*hand)


def _row(table, metric, a, b, kind="between treatments"):
    rows = table[(table["comparison"] == kind) & (table["metric"] == metric)]
    rows = rows[(rows["a"] == a) & (rows["b"] == b)]
    assert len(rows) == 1
    return rows.iloc[0]


def test_stiffness_comparisons_are_at_the_static_common_generation(data):
    table = treatment_comparisons(data, ("best_distance", "distance", "voxel_count", "frequency"))
    for metric in ("best_distance", "distance", "voxel_count", "frequency"):
        row = _row(table, metric, "land S1", "land S3")
        # S3 at generation 2 (20, 21), not at its last, 4 (40, 41); one value per run
        assert row["mean_b"] == pytest.approx(20.5), metric
        assert row["mean_a"] == pytest.approx(1.5), metric
        assert (row["n_a"], row["n_b"]) == (2, 2), metric
        assert row["generation"] == 2 and row["unit"] == "run"
        assert row["A12"] == 0.0  # every S1 run below every S3 run
        assert row["difference"] == pytest.approx(1.5 - 20.5)


def test_transitions_are_compared_with_static_s3_at_their_own_generation(data):
    table = statistics_table(data)
    # land-water ends in water: against land S3 it is a cross-world pair, described only
    row = _row(table, "best_distance", "land S3", "land-water S3", kind="described")
    assert row["generation"] == 4 and row["family"] == "cross-world (described, not tested) | best_distance"
    assert row["mean_a"] == pytest.approx(40.5) and row["mean_b"] == pytest.approx(100.5)
    assert np.isnan(row["p"]) and np.isnan(row["A12"]) and row["test"] == "none (described)"
    # S1 and the transition differ in two factors: not compared
    pairs = set(zip(table["a"], table["b"], strict=True))
    assert ("land S1", "land-water S3") not in pairs
    ends = start_end_comparisons(data, ("distance",)).set_index("a")
    assert ends.loc["land S1 start", "generation"] == 2 and ends.loc["land S3 start", "generation"] == 4
    # the transition's start is its arrival in water (generation 3), not its land start
    assert ends.loc["land-water S3 start", "start_generation"] == 3
    assert ends.loc["land S1 start", "start_generation"] == 0


def test_metrics_identical_to_another_or_constant_are_left_out(data):
    # distance, voxel count and frequency equal the best distance here; active share,
    # symmetry, branching and shape entropy are constant; every robot has an active voxel
    assert distinct_metrics(data) == ("best_distance",)
    table = statistics_table(data)
    assert set(table["metric"]) == {"best_distance"}
    assert set(summary_table(data)["metric"]) == {"best_distance"}


def test_the_loader_reads_the_compared_generations_and_any_other(hand, data):
    static_s3 = data.populations[data.populations["treatment"] == "land S3"]
    assert sorted(static_s3["generation"].unique()) == [0, 2, 3, 4]  # 3: land-water's arrival
    assert data.static_generation == 2 and data.pair_generation("land S3", "land-water S3") == 4
    values = data.run_values(2)
    s3 = values[values["treatment"] == "land S3"]
    assert sorted(s3["distance"]) == [20.0, 21.0] and sorted(s3["best_distance"]) == [20.0, 21.0]
    more = load_experiment(*hand, generations=[1, 3])
    assert sorted(more.populations["generation"].unique()) == [0, 1, 2, 3, 4]
    at_3 = more.run_values(3)
    assert sorted(at_3.loc[at_3["treatment"] == "land S3", "voxel_count"]) == [30.0, 31.0]


def test_summary_names_each_treatments_generations(data):

    summary = summary_table(data)
    best = summary[summary["metric"] == "best_distance"]
    shown = {(r.treatment, r.generation): r.mean for r in best.itertuples()}
    assert shown == pytest.approx(
        {("land S1", 2): 1.5, ("land S3", 2): 20.5, ("land S3", 4): 40.5, ("land-water S3", 4): 100.5}
    )


def test_a_run_cancelled_at_generation_0_is_left_out_not_followed(tmp_path):
    """Issue 49.2: one run cancelled at generation 0 put the whole report at generation 0
    ("start vs end" compared 0 with itself). The comparison is at the last generation the
    finished runs share (2), and the report, the page's analysis and the CLI say which run
    was left out."""
    import warnings

    from softevo.analysis.report import ReportWarning, write_report
    from softevo.evolution.run_status import RunStatus
    from softevo.evolution.treatments import Treatment
    from softevo.service.reports.experiment import experiment_analysis
    from softevo.service.storage.experiments import NewRun, NewTreatment, create_experiment
    from softevo.service.storage.generations import record_generation
    from softevo.service.storage.runs import set_run_status

    engine = open_database(f"sqlite:///{tmp_path / 'cancelled.db'}")
    treatments = [Treatment("land", 0.001, name="land S1", population=2, generations=3),
                  Treatment("land", 0.1, name="land S3", population=2, generations=3)]
    new = [NewTreatment(t.name, t.to_settings(), [NewRun(r, r, t.generations) for r in range(2)])
           for t in treatments]
    with engine.begin() as conn:
        experiment_id, run_ids = create_experiment(conn, "cancelled", new)
    cancelled = run_ids[3]  # land S3, repetition 1
    runs = [(t, r) for t in treatments for r in range(2)]
    for run_id, (treatment, repetition) in zip(run_ids, runs, strict=True):
        for generation in range(1 if run_id == cancelled else treatment.generations):
            record = matched._record(run_id, treatment, repetition, generation, matched.value)
            with engine.begin() as conn:
                record_generation(conn, record)
    with engine.begin() as conn:
        set_run_status(conn, cancelled, RunStatus.CANCELLED)

    data = load_experiment(engine, experiment_id)
    assert data.static_generation == 2 and data.display_generation("land S3") == 2
    row = _row(treatment_comparisons(data, ("best_distance",)), "best_distance", "land S1", "land S3")
    assert row["generation"] == 2 and row["n_b"] == 1  # seed-paired: the cancelled run's seed drops out
    note = f"r{cancelled} (land S3, cancelled after generation 0)"
    assert note in data.left_out_note and "left out of the summary and the tests" in data.left_out_note
    assert note in experiment_analysis(engine, experiment_id)["left_out"]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        report = write_report(data, tmp_path / "report", animation=False)
    assert any(note in str(w.message) for w in caught if issubclass(w.category, ReportWarning))
    assert note in report.markdown.read_text()
    engine.dispose()
