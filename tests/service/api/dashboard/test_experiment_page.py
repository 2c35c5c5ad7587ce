"""The experiment page and the downloads in headless Chromium against ``softevo dashboard``
on the hand-built experiment of ``tests.service.api.dashboard.compared`` (4 treatments x 3 runs): what
the page shows is counted against the API and ``softevo export``, the legends stay clear of
Plotly's toolbar, and ``docs/screenshots.py`` writes a PNG of the page. Skips where Chromium
or Playwright is missing (see conftest)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import httpx
import pandas as pd
import pytest

from tests.service.api.dashboard import compared
from tests.service.api.dashboard.chromium import browser_missing
from tests.service.api.dashboard.conftest import softevo

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(browser_missing() is not None, reason=str(browser_missing())),
]

READY_MS = 120_000  # the analysis starts the server's background process
SCRIPT = Path(__file__).resolve().parents[4] / "docs" / "screenshots.py"
PAGES = ("experiment-page.png", "transition-run-page.png", "individual-page.png")
TREATMENTS = len(compared.TREATMENTS)


@pytest.fixture(scope="module")
def analysis(compared_url, compared_db) -> dict:
    answer = httpx.get(f"{compared_url}/experiments/{compared_db.experiment_id}/analysis", timeout=300)
    assert answer.status_code == 200, answer.text
    return answer.json()


def shown(value: float) -> str:
    """A number as the page writes it (api.js ``fmt``): integers bare, else 3 decimals."""
    return str(int(value)) if float(value).is_integer() else f"{value:.3f}"


def open_experiment(recorded, base: str, experiment_id: int):
    page = recorded.page
    page.goto(f"{base}/dashboard/experiments/{experiment_id}")
    page.wait_for_selector("body[data-analysis=ready]", timeout=READY_MS)
    return page


def test_the_index_links_each_experiment_to_its_page(compared_url, compared_db, open_page):
    page = open_page(compared_url).page
    page.goto(f"{compared_url}/dashboard/")
    page.wait_for_selector("a.experiment-link")
    assert page.locator("a.experiment-link").count() == 2  # compared and empty
    page.click(f"a.experiment-link[href='/dashboard/experiments/{compared_db.experiment_id}']")
    page.wait_for_url(f"**/dashboard/experiments/{compared_db.experiment_id}")
    page.wait_for_selector("body[data-analysis=ready]", timeout=READY_MS)
    assert page.locator("#experiment-title").inner_text() == compared.NAME


def test_the_page_shows_every_treatment_side_by_side(compared_url, compared_db, analysis, open_page):
    page = open_experiment(open_page(compared_url), compared_url, compared_db.experiment_id)
    names = [t.name for t in compared.TREATMENTS]
    assert page.locator("#treatments tbody tr").count() == TREATMENTS
    # fitness: one legend entry and one mean curve per treatment, each with its interval band
    assert page.locator("#fitness .legend .traces").count() == TREATMENTS
    assert page.locator("#fitness .legend .traces").all_text_contents() == names
    # a curve and a band per treatment and world: the transition has a part in each world
    assert page.locator("#fitness .scatterlayer .trace").count() == 2 * (TREATMENTS + 1)
    # one front panel per treatment, each with every member of its runs and its front
    panels = page.locator("#fronts .small-plot")
    assert panels.count() == TREATMENTS
    for k, front in enumerate(analysis["fronts"]):
        panel = panels.nth(k)
        assert panel.get_attribute("data-treatment") == names[k]
        points = panel.locator(".scatterlayer .trace").first.locator(".points path")
        assert points.count() == len(front["points"]["distance"]) == front["members"]
    # one box plot per descriptor, one box per treatment
    boxes = page.locator("#descriptors .small-plot")
    assert boxes.count() == len(analysis["descriptors"]) == 8
    assert boxes.first.locator(".boxlayer .trace").count() == TREATMENTS
    # links to every run
    links = page.locator("#treatments a.run-link")
    runs = [run["run_id"] for t in analysis["treatments"] for run in t["runs"]]
    assert [link.get_attribute("href") for link in links.all()] == [f"/dashboard/runs/{r}" for r in runs]
    links.first.click()
    page.wait_for_url(f"**/dashboard/runs/{runs[0]}")


def test_the_statistics_table_shows_each_p_with_its_family(compared_url, compared_db, analysis, open_page):
    page = open_experiment(open_page(compared_url), compared_url, compared_db.experiment_id)
    rows = analysis["statistics"]
    table = page.locator("#statistics tbody tr")
    # of the hand-built traits only best distance and voxel count vary independently: the
    # statistics drop a metric that is constant or identical to another (issue 46)
    assert {r["metric"] for r in rows} == {"best_distance", "voxel_count"}
    assert table.count() == len(rows) == 16
    assert page.locator("#statistics tbody tr td:last-child").all_inner_texts() == [r["family"] for r in rows]
    page.select_option("#stats-metric", "best_distance")
    chosen = [r for r in rows if r["metric"] == "best_distance"]
    assert table.count() == len(chosen) == 8  # one per pair, and one start vs end per treatment
    page.select_option("#stats-family", "stiffness in land | best_distance")
    assert table.count() == 1
    cells = table.first.locator("td").all_inner_texts()
    best = next(r for r in rows if r["family"] == "stiffness in land | best_distance")
    assert (cells[0], cells[1]) == (best["a"], best["b"])
    assert cells[-1] == best["family"] and cells[-3] == best["test"]
    assert cells[5] == shown(best["p"])
    assert cells[6] == f"{shown(best['p_bonferroni'])} (×1)"
    assert cells[8] == shown(best["A12"])
    assert page.locator("#stats-count").inner_text() == f"1 of {len(rows)} rows"


@pytest.mark.parametrize(("table", "fmt"), [("individuals", "csv"), ("populations", "parquet")])
def test_an_experiment_download_holds_what_softevo_export_writes(
    compared_url, compared_db, open_page, tmp_path, table, fmt
):
    page = open_experiment(open_page(compared_url), compared_url, compared_db.experiment_id)
    with page.expect_download() as info:
        page.click(f"#downloads a:text-is('{table}.{fmt}')")
    path = tmp_path / info.value.suggested_filename
    info.value.save_as(path)
    assert path.name == f"experiment-{compared_db.experiment_id}-{table}.{fmt}"
    softevo(
        "export", f"e{compared_db.experiment_id}", "--out", str(tmp_path / "cli"), "--db", compared_db.url
    )
    expected = pd.read_csv(tmp_path / "cli" / f"{table}.csv")
    downloaded = pd.read_csv(path) if fmt == "csv" else pd.read_parquet(path)
    assert len(downloaded) == len(expected) > 0
    assert downloaded["individual_id"].tolist() == expected["individual_id"].tolist()


def test_a_run_download_holds_what_softevo_export_writes(compared_url, compared_db, open_page, tmp_path):
    page = open_page(compared_url).page
    page.goto(f"{compared_url}/dashboard/runs/2")
    with page.expect_download() as info:
        page.click("#run-downloads a[href*='table=individuals&format=csv']")
    info.value.save_as(tmp_path / "run.csv")
    softevo("export", "2", "--out", str(tmp_path / "cli"), "--db", compared_db.url)
    expected = pd.read_csv(tmp_path / "cli" / "individuals.csv")
    downloaded = pd.read_csv(tmp_path / "run.csv")
    assert len(downloaded) == len(expected) == 3 * 2  # run 2 is land S1: 3 generations x 2 new members
    assert set(downloaded["run_id"]) == {2}


def _overlap(a: dict, b: dict) -> bool:
    return (
        a["x"] < b["x"] + b["width"]
        and b["x"] < a["x"] + a["width"]
        and (a["y"] < b["y"] + b["height"] and b["y"] < a["y"] + a["height"])
    )


@pytest.mark.parametrize("path", ["experiments/1", "runs/1"])
def test_the_plotly_toolbar_leaves_the_legend_visible(compared_url, open_page, path):
    page = open_page(compared_url).page
    page.goto(f"{compared_url}/dashboard/{path}")
    page.wait_for_selector("#fitness .legend .traces", timeout=READY_MS)
    page.hover("#fitness .nsewdrag")  # the toolbar shows while the pointer is over the plot
    toolbar = page.locator("#fitness .modebar")
    toolbar.wait_for(state="visible")
    legend = page.locator("#fitness .infolayer .legend").bounding_box()  # not the hover label's
    assert not _overlap(toolbar.bounding_box(), legend)


def test_the_fitness_plot_has_a_panel_per_world(compared_url, compared_db, open_page):
    """Land and water distances never share an axis: the transition's curve goes on in the
    water panel after its switch, and no band reaches below 0 (issue 49.4)."""
    page = open_experiment(open_page(compared_url), compared_url, compared_db.experiment_id)
    assert page.locator("#fitness").get_attribute("data-worlds") == "land,water"
    traces = page.evaluate(
        "document.getElementById('fitness').data.map((t) => ({name: t.name, x: t.x, y: t.y, yaxis: t.yaxis}))"
    )
    axes = {"land": "y", "water": "y2"}
    for trace in traces:
        if trace["name"] == "land-water S3":
            world = "land" if trace["yaxis"] == "y" else "water"
            expected = [g for g in range(5) if (g >= compared.SWITCH_AT) == (world == "water")]
            assert trace["x"] == expected
        elif trace["name"] in ("land S1", "land S3", "water S3"):
            assert trace["yaxis"] == axes[trace["name"].split()[0]]
        assert min(y for y in trace["y"] if y is not None) >= 0  # bands clipped at 0
    assert sum(trace["name"] == "land-water S3" for trace in traces) == 2
    ticks = page.locator("#fitness .xtick text").all_text_contents()
    assert ticks == [str(g) for g in range(5)]  # whole generations, each once (issue 49.15)


@pytest.mark.parametrize("panels", ["#fronts", "#descriptors"])
def test_the_plotly_toolbar_leaves_small_panel_titles_visible(compared_url, compared_db, open_page, panels):
    page = open_experiment(open_page(compared_url), compared_url, compared_db.experiment_id)
    figures = page.locator(f"{panels} figure.small-panel")
    assert figures.count() > 0
    for k in range(figures.count()):
        figure = figures.nth(k)
        title = figure.locator(".small-title")
        assert title.inner_text().strip()
        figure.locator(".nsewdrag").first.hover()
        toolbar = figure.locator(".modebar")
        toolbar.wait_for(state="visible")
        assert not _overlap(toolbar.bounding_box(), title.bounding_box()), title.inner_text()


def test_the_statistics_table_shows_p_a12_and_the_interval_without_scrolling(
    compared_url, compared_db, browser
):
    """At 1400 px the columns a reader looks for are inside the table's visible box."""
    context = browser.new_context(viewport={"width": 1400, "height": 900})
    try:
        page = context.new_page()
        page.goto(f"{compared_url}/dashboard/experiments/{compared_db.experiment_id}")
        page.wait_for_selector("body[data-analysis=ready]", timeout=READY_MS)
        visible = page.locator("#statistics").bounding_box()
        headers = page.locator("#statistics thead th")
        texts = headers.all_inner_texts()
        for name in ("p", "p (Bonferroni ×k)", "A12", "a − b [95% CI]"):
            box = headers.nth(texts.index(name)).bounding_box()
            assert box["x"] + box["width"] <= visible["x"] + visible["width"], name
    finally:
        context.close()


def test_an_unknown_experiment_is_a_404_page(compared_url):
    answer = httpx.get(f"{compared_url}/dashboard/experiments/999")
    assert answer.status_code == 404 and "There is no experiment 999." in answer.text


def test_the_screenshot_script_saves_the_pages(compared_db, tmp_path):
    """The experiment page whole, the transition run's page and its best individual's page
    (the hand-built genomes replay nothing: the page says so, and is saved all the same)."""
    from PIL import Image

    done = subprocess.run(
        [sys.executable, str(SCRIPT), "--db", compared_db.url, "--experiment", compared.NAME,
         "--out-dir", str(tmp_path), "--width", "1200"],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert done.stdout.count(f"experiment {compared_db.experiment_id}") == 3
    pages = {name: Image.open(tmp_path / name) for name in PAGES}
    assert all(image.width == 1200 for image in pages.values())
    assert pages["experiment-page.png"].height > 2500  # the whole page, every panel
    for image in pages.values():
        assert len(image.convert("RGB").getcolors(1 << 20) or []) > 200  # drawn, not a blank page


def test_qd_panels_show_the_mean_of_the_runs_archives(compared_url, compared_db, analysis, open_page):
    qd = analysis["qd"]
    assert sorted((c["treatment"], c["metric"]) for c in qd) == sorted(
        (t.name, metric) for t in compared.TREATMENTS for metric in ("qd_score", "coverage")
    )
    for treatment in analysis["treatments"]:
        runs = [run["run_id"] for run in treatment["runs"]]
        archives = [httpx.get(f"{compared_url}/runs/{run_id}/archive").json() for run_id in runs]
        for metric in ("qd_score", "coverage"):
            curve = next(c for c in qd if c["treatment"] == treatment["name"] and c["metric"] == metric)
            assert curve["generation"][-1] == archives[0]["generation"]
            assert curve["environment"][-1] == archives[0]["environment"]
            values = [archive[metric] for archive in archives]
            assert curve["n"][-1] == len(values) == compared.REPETITIONS
            assert curve["mean"][-1] == pytest.approx(sum(values) / len(values))
            assert curve["low"][-1] <= curve["mean"][-1] <= curve["high"][-1]
    page = open_experiment(open_page(compared_url), compared_url, compared_db.experiment_id)
    for metric in ("qd_score", "coverage"):
        panel = page.locator(f"#qd-{metric}")
        panel.locator(".scatterlayer .trace").first.wait_for(timeout=READY_MS)
        assert panel.locator(".scatterlayer .trace").count() == 2 * TREATMENTS  # a band and a mean each
