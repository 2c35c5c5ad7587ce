"""``GET /experiments/{id}/analysis`` and the downloads (``GET /runs/{id}/export``,
``GET /experiments/{id}/export``) over real HTTP (``softevo dashboard`` on loopback, SQLite),
checked against ``softevo export`` and against statistics computed here from the stored
values (``tests.service.api.dashboard.compared``)."""

from __future__ import annotations

import io

import httpx
import numpy as np
import pandas as pd
import pytest
from scipy import stats
from sqlalchemy import create_engine

from softevo.analysis.matching import families
from softevo.analysis.stats_tables import distinct_metrics
from softevo.evolution.traits import names as trait_names
from softevo.service.api.expensive import Busy
from softevo.service.api.routes.exports import Downloads
from softevo.service.api.schemas_analysis import ExperimentAnalysisOut
from softevo.service.reports.data import load_experiment
from softevo.service.storage.export import table_chunks
from softevo.service.storage.export_stream import stream_table
from tests.service.api.dashboard import compared
from tests.service.api.dashboard.conftest import softevo

TABLES = ("runs", "individuals", "populations")


def get(base: str, path: str, **params) -> httpx.Response:
    return httpx.get(f"{base}{path}", params=params, timeout=300)


@pytest.fixture(scope="module")
def cli_export(compared_db, tmp_path_factory):
    """``softevo export eID`` and ``softevo export RUN`` (the first run) as the user runs them."""
    out = tmp_path_factory.mktemp("cli-export")
    softevo(
        "export", f"e{compared_db.experiment_id}", "--out", str(out / "experiment"), "--db", compared_db.url
    )
    softevo("export", "1", "--out", str(out / "run"), "--db", compared_db.url)
    return out


@pytest.fixture(scope="module")
def analysis(compared_url, compared_db) -> dict:
    answer = get(compared_url, f"/experiments/{compared_db.experiment_id}/analysis")
    assert answer.status_code == 200, answer.text
    return answer.json()


@pytest.mark.parametrize("table", TABLES)
def test_an_experiments_csv_download_equals_softevo_export(compared_url, compared_db, cli_export, table):
    answer = get(compared_url, f"/experiments/{compared_db.experiment_id}/export", table=table, format="csv")
    assert answer.status_code == 200
    assert answer.headers["content-type"].startswith("text/csv")
    assert f"experiment-{compared_db.experiment_id}-{table}.csv" in answer.headers["content-disposition"]
    assert "content-length" not in answer.headers  # streamed
    expected = (cli_export / "experiment" / f"{table}.csv").read_bytes()
    downloaded = pd.read_csv(io.BytesIO(answer.content))
    assert len(downloaded) == len(pd.read_csv(io.BytesIO(expected))) > 0
    assert answer.content == expected


@pytest.mark.parametrize("table", TABLES)
def test_a_runs_parquet_download_holds_the_rows_of_softevo_export(compared_url, cli_export, table):
    answer = get(compared_url, "/runs/1/export", table=table, format="parquet")
    assert answer.status_code == 200
    assert answer.headers["content-type"] == "application/vnd.apache.parquet"
    downloaded = pd.read_parquet(io.BytesIO(answer.content))
    expected = pd.read_csv(cli_export / "run" / f"{table}.csv")
    assert list(downloaded.columns) == list(expected.columns)
    assert len(downloaded) == len(expected) > 0
    assert set(downloaded["run_id"]) == {1}
    if table == "individuals":
        assert downloaded["distance"].tolist() == pytest.approx(expected["distance"].tolist())


def test_an_experiment_without_runs_downloads_the_header_alone(compared_url, compared_db):
    answer = get(compared_url, f"/experiments/{compared_db.empty_id}/export", table="individuals")
    assert answer.status_code == 200
    assert answer.text.strip().startswith("individual_id,run_id,parent_id") and answer.text.count("\n") == 1


@pytest.mark.parametrize(
    ("path", "params", "status"),
    [
        ("/runs/999/export", {}, 404),
        ("/experiments/999/export", {}, 404),
        ("/runs/1/export", {"format": "xlsx"}, 422),
        ("/runs/1/export", {"table": "genomes"}, 422),
        ("/experiments/999/analysis", {}, 404),
    ],
)
def test_bad_downloads_and_analyses_are_clear_errors(compared_url, path, params, status):
    answer = get(compared_url, path, **params)
    assert answer.status_code == status
    assert answer.json()["detail"]


def test_an_experiment_with_nothing_stored_has_no_analysis(compared_url, compared_db):
    answer = get(compared_url, f"/experiments/{compared_db.empty_id}/analysis")
    assert answer.status_code == 404 and "no stored generation" in answer.json()["detail"]


def test_tables_are_read_a_bounded_chunk_at_a_time(compared_db):
    engine = create_engine(compared_db.url)
    with engine.connect() as conn:
        sizes = [len(frame) for frame in table_chunks(conn, "individuals", [1, 2, 3], chunk_rows=4)]
    total = sum(sizes)
    assert max(sizes) == 4 and len(sizes) == -(-total // 4)  # every chunk full but the last
    import pyarrow.parquet as pq

    from softevo.service.storage import export_stream

    original = export_stream.table_chunks
    export_stream.table_chunks = lambda conn, table, run_ids: original(conn, table, run_ids, chunk_rows=4)
    try:
        body = b"".join(stream_table(engine, "individuals", [1, 2, 3], "parquet"))
        csv = b"".join(stream_table(engine, "individuals", [1, 2, 3], "csv"))
    finally:
        export_stream.table_chunks = original
    metadata = pq.ParquetFile(io.BytesIO(body)).metadata
    assert (metadata.num_row_groups, metadata.num_rows) == (len(sizes), total)
    assert csv.count(b"\n") == total + 1 and csv.count(b"individual_id") == 1  # one header
    engine.dispose()


def test_downloads_beyond_the_limit_are_busy():
    downloads = Downloads(2)
    downloads.enter()
    downloads.enter()
    with pytest.raises(Busy):
        downloads.enter()
    downloads.leave()
    downloads.enter()  # a slot freed is taken again


def test_the_analysis_matches_its_schema_and_is_cached(compared_url, compared_db, analysis):
    ExperimentAnalysisOut.model_validate(analysis)
    again = get(compared_url, f"/experiments/{compared_db.experiment_id}/analysis")
    assert again.headers["x-cache"] == "hit" and again.json() == analysis


def test_the_analysis_has_one_curve_front_and_box_per_treatment(analysis):
    names = [t.name for t in compared.TREATMENTS]
    assert [t["name"] for t in analysis["treatments"]] == names
    assert [c["treatment"] for c in analysis["curves"]] == names
    assert [f["treatment"] for f in analysis["fronts"]] == names
    assert [d["metric"] for d in analysis["descriptors"]] == ["best_distance", *trait_names()]
    for descriptor in analysis["descriptors"]:
        assert [len(t["values"]) for t in descriptor["treatments"]] == [compared.REPETITIONS] * len(names)
    runs = [run["run_id"] for t in analysis["treatments"] for run in t["runs"]]
    assert runs == list(range(1, 1 + compared.REPETITIONS * len(names)))


def test_the_curves_are_t_intervals_over_the_runs(analysis):
    """At every generation: its world, the mean of the runs' best distances and mean -+ t sd
    / sqrt(n), clipped at 0 (a distance is never negative; issue 49.4)."""
    clipped = 0
    for treatment, curve in zip(compared.TREATMENTS, analysis["curves"], strict=True):
        assert curve["generation"] == list(range(treatment.generations))
        assert curve["environment"] == [treatment.environment_at(g) for g in curve["generation"]]
        for k, generation in enumerate(curve["generation"]):
            values = np.array(
                [compared.value(treatment.name, r, generation) for r in range(compared.REPETITIONS)]
            )
            half = stats.t.ppf(0.975, len(values) - 1) * values.std(ddof=1) / np.sqrt(len(values))
            assert curve["n"][k] == compared.REPETITIONS
            assert curve["mean"][k] == pytest.approx(values.mean())
            assert (curve["low"][k], curve["high"][k]) == pytest.approx(
                (max(0.0, values.mean() - half), values.mean() + half)
            )
            clipped += values.mean() - half < 0
    assert clipped > 0  # the water curves' t intervals reach below 0: these are clipped


def test_the_fronts_are_the_non_dominated_members(analysis):
    for front in analysis["fronts"]:
        points = np.column_stack([front["points"]["distance"], front["points"]["active_share"]])
        dominated = [any(q[0] >= p[0] and q[1] <= p[1] and (q != p).any() for q in points) for p in points]
        ids = zip(front["points"]["individual_id"], front["points"]["run_id"], strict=True)
        expected = sorted(key for key, out in zip(ids, dominated, strict=True) if not out)
        found = sorted(zip(front["front"]["individual_id"], front["front"]["run_id"], strict=True))
        assert found == expected
        assert front["members"] == len(front["points"]["distance"]) == compared.REPETITIONS * 2


def test_the_statistics_table_holds_every_family(analysis, compared_db):
    data = load_experiment(create_engine(compared_db.url), compared_db.experiment_id)
    pairs = families(data.treatments)
    assert {pair.question for pair in pairs} == {
        "stiffness in land",
        "land-water S3 vs its final world",
        "cross-world (described, not tested)",
    }
    metrics = distinct_metrics(data)  # METRICS less the constant or repeated ones
    between = [f"{pair.question} | {metric}" for metric in metrics for pair in pairs]
    start_end = [f"start vs end | {metric}" for metric in metrics for _ in compared.TREATMENTS]
    rows = analysis["statistics"]
    assert [row["family"] for row in rows] == between + start_end
    tested = [row for row in rows if row["comparison"] == "between treatments"]
    assert tested and all(row["p"] is not None and row["A12"] is not None for row in tested)
    described = [row for row in rows if row["comparison"] == "described"]
    assert described and all(row["p"] is None for row in described)
    # land S3 beats land S1 in every seed-matched pair: A12 = 0 for a = S1
    best = next(r for r in rows if r["family"] == "stiffness in land | best_distance")
    assert (best["a"], best["b"], best["A12"], best["family_size"]) == ("land S1", "land S3", 0.0, 1)
    assert best["test"].startswith("Wilcoxon signed-rank")


def test_a_transition_runs_best_is_its_last_worlds(compared_url, compared_db):
    """A land -> water run's ``best`` is its best robot in water, the world it ended in, not
    the land robot of greater distance (distances of two worlds are not comparable); every
    world's best is listed too (issue 49.4)."""
    names = [t.name for t in compared.TREATMENTS]
    run_id = names.index("land-water S3") * compared.REPETITIONS + compared.REPETITIONS  # its last run
    repetition = compared.REPETITIONS - 1
    run = get(compared_url, f"/runs/{run_id}").json()
    assert run["treatment"]["name"] == "land-water S3"
    assert (run["best"]["environment"], run["best"]["generation"]) == ("water", 4)
    assert run["best"]["distance"] == pytest.approx(compared.value("land-water S3", repetition, 4))
    worlds = [(b["environment"], b["generation"]) for b in run["best_per_world"]]
    assert worlds == [("land", 2), ("water", 4)]
    assert run["best_per_world"] == get(compared_url, f"/runs/{run_id}/best").json()
    assert run["best_per_world"][0]["distance"] > run["best"]["distance"]  # the land one goes further
