"""The report on the paper's grid at the tiny scale, made by the CLI end to end (slow)."""

from __future__ import annotations

import pytest

from softevo.analysis.figures import FIGURES
from tests.analysis.cli import softevo


@pytest.mark.slow
def test_report_on_the_tiny_paper_grid(capsys, tmp_path):
    db = f"sqlite:///{tmp_path / 'paper.db'}"
    code, _, err = softevo(capsys, "experiment", "paper", "--scale", "tiny", "--db", db, "--quiet")
    assert code == 0, err
    out = tmp_path / "report"
    code, _, err = softevo(capsys, "report", "paper-tiny", "--out", str(out), "--db", db, "--quiet")
    assert code == 0, err
    page = (out / "report.html").read_text(encoding="utf-8")
    for name in FIGURES:
        assert f'<figure id="{name}">' in page
    for treatment in ("land S1", "water S5", "land-water S3", "water-land S3"):
        assert treatment in page
    markdown = (out / "report.md").read_text(encoding="utf-8")
    assert markdown.count("](figures/") == 2 * len(FIGURES) + 1  # PNG and SVG links, + the GIF
