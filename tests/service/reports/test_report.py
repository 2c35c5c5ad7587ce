"""``softevo report`` / ``write_report`` on a real tiny experiment: every figure is in it."""

from __future__ import annotations

import base64
import re

import pytest

from softevo.analysis.figures import FIGURES, TITLES
from softevo.service.reports.report import report_html, write_report
from tests.support import softevo


@pytest.fixture(scope="module")
def report(tiny, tmp_path_factory):
    out = tmp_path_factory.mktemp("report")
    return write_report(tiny.url, tiny.experiment_id, out), out


def test_report_writes_every_figure_and_table(report):
    result, out = report
    assert [f.name for f in result.figures] == list(FIGURES)
    for name in FIGURES:
        assert (out / "figures" / f"{name}.png").stat().st_size > 0
        assert (out / "figures" / f"{name}.svg").stat().st_size > 0
    assert result.animation == out / "figures" / "best.gif"
    assert result.statistics.read_text().startswith("comparison,family,family_size,test,metric,unit,a,b")
    assert "best_distance" in result.summary.read_text()


def test_html_is_self_contained_and_embeds_every_figure(report):
    result, out = report
    page = result.html.read_text(encoding="utf-8")
    assert 'src="figures/' not in page and "<img" in page
    for figure in result.figures:
        match = re.search(
            rf'<figure id="{figure.name}"><img alt="[^"]*" src="data:image/png;base64,([^"]+)"', page
        )
        assert match, figure.name
        assert base64.b64decode(match.group(1)) == figure.png.read_bytes()
        assert TITLES[figure.name] in page
    assert 'src="data:image/gif;base64,' in page
    for text in ("Run settings", "Summary", "Statistics", "Mann-Whitney", "land S3", "water-land S3"):
        assert text in page
    # the statistics section names each p's family, the test used and the interval method
    for text in (
        "water-land S3 vs its final world | best_distance",
        "Wilcoxon signed-rank (seed-matched runs)",
        "Wilcoxon signed-rank (the same runs)",
        "Student t over runs (95%)",
        "paired t (95%)",
        "detectable_A12",
        "passive robots (share)",
        "frequency, active robots (Hz)",
    ):
        assert text in page, text
    assert "water:0,land:2" in page  # the transition's schedule
    assert "Wall time" in page and "Evaluation: voxel edge 0.05 m" in page


def test_markdown_links_every_figure_and_holds_the_tables(report):
    result, out = report
    text = result.markdown.read_text(encoding="utf-8")
    for name in FIGURES:
        assert f"](figures/{name}.png)" in text and f"(figures/{name}.svg)" in text
    assert "](figures/best.gif)" in text
    assert "## Run settings" in text and "## Statistics" in text
    assert "| comparison | family | family_size | test | metric | a | b |" in text
    assert "| land S3 | land:0 | 0.1 | 4 | 3 | 4x4x4 | 2 | 3 | 0..2 | afpo | 3/3 |" in text


def test_report_command(capsys, tiny, tmp_path):
    code, out, err = softevo(
        capsys,
        "report",
        f"e{tiny.experiment_id}",
        "--out",
        str(tmp_path / "r"),
        "--db",
        tiny.url,
        "--no-animation",
        "--quiet",
    )
    assert code == 0, err
    assert out.split() == [str(tmp_path / "r" / "report.html"), str(tmp_path / "r" / "report.md")]
    assert not (tmp_path / "r" / "figures" / "best.gif").exists()


def test_report_html_for_the_rest_service(tiny):
    page = report_html(tiny.engine, tiny.experiment_id)
    assert page.startswith("<!DOCTYPE html>") and page.count("data:image/png;base64,") == len(FIGURES)


@pytest.mark.parametrize(
    ("reference", "message"), [("e999", "no experiment 'e999'"), ("nope", "no experiment 'nope'")]
)
def test_unknown_experiment_is_one_line_and_exit_2(capsys, tiny, tmp_path, reference, message):
    code, _, err = softevo(capsys, "report", reference, "--out", str(tmp_path), "--db", tiny.url, "-q")
    assert code == 2
    assert err.startswith("error: ") and err.count("\n") == 1 and message in err


def test_an_experiment_with_nothing_stored_yet_is_a_user_error(capsys, tmp_path):
    from softevo.evolution.treatments import Treatment
    from softevo.service.runs.submit import create
    from softevo.service.storage import open_database

    url = f"sqlite:///{tmp_path / 'empty.db'}"
    engine = open_database(url)
    experiment_id, _ = create(engine, "not-started", [Treatment("land", 0.1, population=4, generations=2)])
    code, _, err = softevo(capsys, "report", f"e{experiment_id}", "--out", str(tmp_path / "r"), "--db", url)
    assert code == 2 and f"experiment e{experiment_id} has no stored generation yet" in err


def test_the_analysis_report_needs_only_the_data(tiny_data, tmp_path):
    from softevo.analysis.report import write_report as write_from_data

    result = write_from_data(tiny_data, tmp_path, robots=None)
    # the exaptation and QD figures need the phylogeny and the archives, given as exaptation= and
    # qd= (service.reports.report does)
    needing_more = ("robots", "exaptation", "qd")
    assert [f.name for f in result.figures] == [name for name in FIGURES if name not in needing_more]
    assert result.animation is None
    assert "Evaluation: voxel edge" not in result.html.read_text(encoding="utf-8")


def test_a_report_of_single_runs_warns_that_its_statistics_say_nothing(capsys, tiny, tmp_path):
    url = f"sqlite:///{tmp_path / 'one.db'}"
    code, _, err = softevo(capsys, "run", "--env", "water", "--stiffness", "0.1", "--population", "3",
                           "--generations", "2", "--workspace", "3,3,3", "--cycles", "1", "--workers", "0",
                           "-q", "--db", url)  # fmt: skip
    assert code == 0, err
    out = tmp_path / "r"
    code, _, err = softevo(capsys, "report", "latest", "--out", str(out), "--db", url, "--no-animation", "-q")
    assert code == 0, err
    warning = [line for line in err.splitlines() if line.startswith("warning: ")]
    assert len(warning) == 1 and "1 of 1 treatment(s) have fewer than 3 runs (water S=0.1MPa)" in warning[0]
    markdown = (out / "report.md").read_text()
    assert "n = 1: not tested, no interval" in markdown  # was: degenerate CIs, no word
    # issue 59.3: it listed 10 tests, all p = 1, and "no pair differs" with one treatment
    statistics = markdown.split("## Statistics")[1]
    assert "No pairwise test: n = 1: not tested" in statistics and "| p |" not in statistics
    assert "| ns |" not in markdown and "no pair differs" not in markdown
    import pandas as pd

    rows = pd.read_csv(out / "statistics.csv")
    assert rows["p"].isna().all() and (rows["test"] == "n = 1: not tested").all()
    code, _, err = softevo(capsys, "report", f"e{tiny.experiment_id}", "--out", str(tmp_path / "three"),
                           "--db", tiny.url, "--no-animation", "-q")  # fmt: skip
    assert code == 0 and "warning" not in err  # 3 repetitions: no warning


def test_the_report_writes_the_findings_and_one_summary_row_per_run(report, tiny):
    import pandas as pd

    from softevo.analysis.findings import FINDING_COLUMNS
    from softevo.analysis.run_summary import SUMMARY_COLUMNS

    result, out = report
    findings = pd.read_csv(result.findings)
    assert list(findings.columns) == FINDING_COLUMNS
    # the tiny experiment holds one transition and its final world's control: its two contrasts
    assert len(findings) == 2 and findings["question"].str.startswith("water-land S3 vs land S3").all()
    summary = pd.read_csv(result.summary)
    assert list(summary.columns) == SUMMARY_COLUMNS and sorted(summary["run_id"]) == sorted(tiny.run_ids)
    assert (out / "treatment_summary.csv").read_text().startswith("metric,treatment,generation,n,mean")
    page = result.html.read_text(encoding="utf-8")
    assert page.index("<h2>Findings</h2>") < page.index("<h2>Run settings</h2>")
    assert "Jonckheere-Terpstra" in page and "p_holm" in page


def test_the_methods_paragraph_comes_from_each_treatments_settings(report):
    page = report[0].html.read_text(encoding="utf-8")
    # the tiny experiment's treatments: the default model and the linear 1-5 Hz mapping, no cap
    assert "physics model voxelyze-2; frequency: one evolved frequency mapped linearly onto 1-5 Hz" in page
    assert "land S3: physics model" in page and "water-land S3: physics model" in page
    assert "2 actuation cycles per evaluation, no cap on seconds" in page


def test_report_numbers_say_zero_and_no_interval_plainly():
    """Floating-point noise around 0 reads 0, and one run has no interval instead of
    ``[nan, nan]`` (issue 49.15)."""
    from softevo.analysis.report import _cell, interval_cell

    assert _cell(3.93e-16) == "0" and _cell(-2e-17) == "0" and _cell(0.0001234) == "0.0001234"
    assert interval_cell(1.5, float("nan"), float("nan")) == "1.5 (n < 3: no interval)"
    assert interval_cell(3.93e-16, -1e-16, 2e-16) == "0 [0, 0]"
    assert interval_cell(2.0, 1.25, 2.75) == "2 [1.25, 2.75]"
    assert interval_cell(float("nan"), float("nan"), float("nan")) == ""


def test_qd_figure_and_table_are_the_runs_archives(report, tiny):
    """qd.csv's mean at each treatment's last generation is the mean over its runs of their
    archives (``service.storage.archive.run_archive``), and the report has the QD section."""
    import pandas as pd

    from softevo.service.storage.archive import run_archive

    result, out = report
    curves = pd.read_csv(out / "qd.csv")
    assert set(curves["metric"]) == {"qd_score", "coverage"}
    with tiny.engine.connect() as conn:
        archives = {run_id: run_archive(conn, run_id) for run_id in tiny.run_ids}
    runs = pd.read_csv(out / "summary.csv")[["run_id", "treatment"]]
    for name, part in runs.groupby("treatment"):
        last = curves[(curves["treatment"] == name) & (curves["metric"] == "qd_score")].iloc[-1]
        values = [archives[int(run_id)]["qd_score"] for run_id in part["run_id"]]
        assert int(last["generation"]) == archives[int(part["run_id"].iloc[0])]["generation"]
        assert last["n"] == len(values) and last["mean"] == pytest.approx(sum(values) / len(values))
    page = result.html.read_text(encoding="utf-8")
    assert "Quality-diversity" in page and '<figure id="qd">' in page


def test_a_minimised_objectives_best_is_over_robots_with_an_active_voxel(tiny_data):
    """Issue 59.3: the "best" voxel count was a 1-voxel passive body, the trivial optimum."""
    from softevo.analysis.report import objectives_table

    table = objectives_table(tiny_data)
    members = tiny_data.display_populations()
    for name in ("land S3", "water-land S3"):
        active = members[(members["treatment"] == name) & (members["active_share"] > 0)]
        rows = table[table["treatment"] == name].set_index("objective")
        assert rows.loc["voxel_count", "best"] == active["voxel_count"].min()
        assert rows.loc["active_share", "best"] == pytest.approx(active["active_share"].min())
        assert rows.loc["active_share", "best"] > 0
