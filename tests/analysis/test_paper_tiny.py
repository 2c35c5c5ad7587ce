"""The paper's grid at the tiny scale, run once by the CLI end to end (slow): every run
finishes, the export holds them, the transitions visit both worlds, and the report shows every
figure and treatment."""

from __future__ import annotations

import contextlib
import io

import pandas as pd
import pytest

from softevo.analysis.figures import FIGURES
from tests.support import exit_code, softevo


@pytest.fixture(scope="module")
def paper_tiny(tmp_path_factory) -> str:
    """The database of ``softevo experiment paper --scale tiny --repetitions 3`` on 2 worker
    processes: 3 runs a treatment, the fewest the findings test (issue 59.3)."""
    db = f"sqlite:///{tmp_path_factory.mktemp('paper-tiny') / 'paper.db'}"
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        code = exit_code("experiment", "paper", "--scale", "tiny", "--repetitions", "3", "--workers", "2",
                         "--db", db, "--quiet")
    assert code == 0, err.getvalue()
    return db


@pytest.mark.slow
def test_every_run_of_the_tiny_paper_grid_is_stored(capsys, tmp_path, paper_tiny):
    code, _, err = softevo(capsys, "export", "latest", "--out", str(tmp_path / "out"), "--db", paper_tiny)
    assert code == 0, err
    runs = pd.read_csv(tmp_path / "out" / "runs.csv")
    assert len(runs) == 36 and set(runs["status"]) == {"finished"}
    assert sorted(runs["stiffness_pa"].unique()) == [1e3, 1e4, 1e5, 1e6, 1e7]
    individuals = pd.read_csv(tmp_path / "out" / "individuals.csv")
    switching = runs[runs["environment_schedule"].str.contains(",")]["run_id"]
    assert len(switching) == 6
    for run_id in switching:
        assert set(individuals[individuals["run_id"] == run_id]["environment"]) == {"land", "water"}


@pytest.mark.slow
def test_report_on_the_tiny_paper_grid(capsys, tmp_path, paper_tiny):
    out = tmp_path / "report"
    code, _, err = softevo(capsys, "report", "paper-tiny", "--out", str(out), "--db", paper_tiny, "--quiet")
    assert code == 0, err
    page = (out / "report.html").read_text(encoding="utf-8")
    for name in FIGURES:
        assert f'<figure id="{name}">' in page
    for treatment in ("land S1", "water S5", "land-water S3", "water-land S3"):
        assert treatment in page
    markdown = (out / "report.md").read_text(encoding="utf-8")
    assert markdown.count("](figures/") == 2 * len(FIGURES) + 1  # PNG and SVG links, + the GIF


@pytest.mark.slow
def test_findings_and_per_run_summary_on_the_tiny_paper_grid(capsys, tmp_path, paper_tiny):
    out = tmp_path / "report"
    code, _, err = softevo(
        capsys, "report", "paper-tiny", "--out", str(out), "--db", paper_tiny, "--quiet", "--no-animation"
    )
    assert code == 0, err
    findings = pd.read_csv(out / "findings.csv")
    # primary: four trends and the transitions' paper contrasts; gain: the distance trends'
    # absolute and log gains; secondary: the frequency levels and the equal-time contrasts
    assert findings["family"].tolist() == ["primary"] * 6 + ["gain"] * 4 + ["secondary"] * 4
    assert findings["p_holm"].iloc[:6].notna().all() and findings["verdict"].notna().all()
    summary = pd.read_csv(out / "summary.csv")
    assert len(summary) == 36 and summary["run_id"].is_unique
    assert summary["distance_per_second"].notna().all()


@pytest.mark.slow
def test_recompute_gives_every_number_of_the_results_page_from_the_export(capsys, tmp_path, paper_tiny):
    """docs/results/recompute.py on the tiny grid's report and export: --write fills the
    template; the check then finds every finding, design and number again (exit 0), and
    exits 1 when a number of the page or of findings.csv is changed."""
    import runpy
    import shutil
    from pathlib import Path

    results = tmp_path / "results"
    code, _, err = softevo(capsys, "report", "paper-tiny", "--out", str(results), "--db", paper_tiny,
                           "--quiet", "--no-animation")
    assert code == 0, err
    code, _, err = softevo(capsys, "export", "latest", "--out", str(results / "export"), "--db", paper_tiny)
    assert code == 0, err
    docs = Path(__file__).resolve().parents[2] / "docs" / "results"
    shutil.copy(docs / "README.template.md", results)
    recompute = runpy.run_path(str(docs / "recompute.py"))
    assert recompute["main"](results, write=True) == 0
    assert recompute["main"](results) == 0
    page = (results / "README.md").read_text()
    assert "{" not in page and "| land distance rises with stiffness (S2, S3, S4, S5) |" in page
    (results / "README.md").write_text(page.replace("evaluations (", "evaluations (1", 1))
    assert recompute["main"](results) == 1
    (results / "README.md").write_text(page)
    findings = pd.read_csv(results / "findings.csv")
    findings.loc[0, "p"] = findings.loc[0, "p"] * 0.5
    findings.to_csv(results / "findings.csv", index=False)
    assert recompute["main"](results) == 1
