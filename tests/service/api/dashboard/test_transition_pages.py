"""A transition run's pages read per world (issue 49.4, 49.14), in headless Chromium against
``softevo dashboard`` on a real land -> water run made with the CLI: the run page names the
best robot of each world, the last world's last, each link opening the individual in that
world; the individual page shows the world its link named (else its last); a water replay
draws no floor grid; the phylogeny tree labels its y axis."""

from __future__ import annotations

import httpx
import pytest

from tests.service.api.dashboard.chromium import browser_missing
from tests.service.api.dashboard.conftest import softevo

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(browser_missing() is not None, reason=str(browser_missing())),
]

REPLAY_READY_MS = 240_000  # the server simulates the evaluation again for the frames
SWITCH_AT, GENERATIONS = 2, 4


@pytest.fixture(scope="module")
def transition(tmp_path_factory, start_server) -> str:
    """Base URL of ``softevo dashboard`` on run 1: land -> water at generation 2, 4 robots."""
    url = f"sqlite:///{tmp_path_factory.mktemp('transition') / 'transition.db'}"
    softevo(
        "run", "--env", "land-water", "--stiffness", "0.1", "--population", "4",
        "--generations", str(GENERATIONS), "--switch-at", str(SWITCH_AT), "--workspace", "3,3,3",
        "--cycles", "2", "--db", url, "-q",
    )  # fmt: skip
    return start_server("dashboard", url)


@pytest.fixture(scope="module")
def both_worlds(transition) -> int:
    """An individual of the last generation evaluated on land and in water (a survivor of
    the switch, re-evaluated in water)."""
    front = httpx.get(f"{transition}/runs/1/front", params={"generation": GENERATIONS - 1}).json()
    for member in front["individuals"]:
        individual = httpx.get(f"{transition}/individuals/{member['id']}").json()
        if {e["environment"] for e in individual["evaluations"]} == {"land", "water"}:
            return member["id"]
    pytest.fail("no individual of the last generation was evaluated in both worlds")


def open_individual(page, base: str, individual_id: int, query: str = ""):
    page.goto(f"{base}/dashboard/individuals/{individual_id}{query}")
    page.wait_for_function("window.softevoReplay !== undefined", timeout=REPLAY_READY_MS)
    page.wait_for_selector("#play:not([disabled])")
    return page


def test_the_run_page_names_the_best_of_each_world(transition, open_page):
    page = open_page(transition).page
    page.goto(f"{transition}/dashboard/runs/1")
    page.wait_for_selector("#run-facts .best")
    bests = httpx.get(f"{transition}/runs/1/best").json()
    shown = page.locator("#run-facts .best")
    assert [shown.nth(k).get_attribute("data-environment") for k in range(shown.count())] == ["land", "water"]
    assert [b["environment"] for b in bests] == ["land", "water"]
    for k, best in enumerate(bests):
        text = shown.nth(k).inner_text()
        assert text.startswith(f"best in {best['environment']} individual {best['individual_id']}"), text
        href = shown.nth(k).locator("a").get_attribute("href")
        assert href == f"/dashboard/individuals/{best['individual_id']}?environment={best['environment']}"
    run = httpx.get(f"{transition}/runs/1").json()
    assert run["best"] == bests[-1]  # the run's best is its last world's


def test_the_individual_page_shows_the_world_its_link_named(transition, both_worlds, open_page):
    page = open_individual(open_page(transition).page, transition, both_worlds, "?environment=land")
    assert page.locator("#environment").input_value() == "land"
    assert page.locator("#replay-environment").inner_text().startswith("land ·")
    assert "distance in land" in page.locator("#objectives").inner_text()
    page = open_individual(open_page(transition).page, transition, both_worlds)
    assert page.locator("#environment").input_value() == "water"  # no world named: its last
    assert "distance in water" in page.locator("#objectives").inner_text()


def test_a_water_replay_draws_no_floor_grid(transition, both_worlds, open_page):
    page = open_individual(open_page(transition).page, transition, both_worlds, "?environment=water")
    assert page.evaluate("window.softevoReplay.grid === null")
    page.select_option("#environment", "land")
    page.wait_for_function(
        "window.softevoReplay && window.softevoReplay.grid !== null", timeout=REPLAY_READY_MS
    )
    assert page.locator("#replay-environment").inner_text().startswith("land ·")


RECORD_CANVAS_TEXT = """
window.canvasTexts = [];
const fillText = CanvasRenderingContext2D.prototype.fillText;
CanvasRenderingContext2D.prototype.fillText = function (text, ...rest) {
  window.canvasTexts.push(String(text));
  return fillText.call(this, text, ...rest);
};
"""


def test_the_tree_labels_its_y_axis(transition, open_page):
    page = open_page(transition).page
    page.add_init_script(RECORD_CANVAS_TEXT)
    page.goto(f"{transition}/dashboard/runs/1/tree")
    page.wait_for_function("window.softevoTree !== undefined", timeout=60_000)
    texts = page.evaluate("window.canvasTexts")
    assert "generation" in texts
    assert any(text.startswith("lineages") for text in texts), texts
    assert "surviving" in texts


def test_the_clock_counts_a_cut_short_cycle(transition, both_worlds, open_page):
    """An evaluation the guard on seconds cut short of a whole cycle (0.96 s of a 2.03 s
    period, as at the tiny scale) reads "cycle 1 of 0.5", not "cycle 0 of 0"."""
    page = open_individual(open_page(transition).page, transition, both_worlds)
    clock = page.evaluate(
        """(() => {
          const r = window.softevoReplay;
          r.omega = 2 * Math.PI * 0.492;
          r.end = r.settle + 0.96;
          r.time = r.end - 0.01;
          return r.clock();
        })()"""
    )
    assert (clock["settling"], clock["cycle"], clock["cycles"]) == (False, 1, 0.5)


def test_the_run_page_plots_each_world_in_its_own_panel(transition, open_page):
    """No line joins a land distance to a water one: a panel per world, each with its own
    axis, the land generations in one, the water ones in the other."""
    page = open_page(transition).page
    page.goto(f"{transition}/dashboard/runs/1")
    page.wait_for_selector("#fitness .scatterlayer .trace", timeout=60_000)
    assert page.locator("#fitness").get_attribute("data-worlds") == "land,water"
    traces = page.evaluate("document.getElementById('fitness').data.map((t) => ({x: t.x, yaxis: t.yaxis}))")
    land = [t["x"] for t in traces if t["yaxis"] == "y"]
    water = [t["x"] for t in traces if t["yaxis"] == "y2"]
    assert land == [list(range(SWITCH_AT))] * 2  # best and mean
    assert water == [list(range(SWITCH_AT, GENERATIONS))] * 2
