"""The phylogeny tree page in headless Chromium against a real server: on a tiny gradual
water->land run (made with the CLI, ``--switch-over``) it draws every node the server
picked, survivors highlighted, coloured by world (compound worlds too), and a node click
opens the individual; on a synthetic 30 x 9000-generation run it draws a bounded sample
quickly. The screenshots go to docs/ (phylogeny-tree.png, phylogeny-tree-9000.png)."""

from __future__ import annotations

import time
from pathlib import Path

import httpx
import numpy as np
import pytest

from softevo.service.storage import open_database
from tests.service.api.dashboard import synthetic
from tests.service.api.dashboard.chromium import browser_missing
from tests.service.api.dashboard.conftest import softevo
from tests.service.api.dashboard.test_browser import pixels
from tests.service.api.dashboard.test_transition_pages import RECORD_CANVAS_TEXT

pytestmark = pytest.mark.skipif(browser_missing() is not None, reason=str(browser_missing()))

DOCS = Path(__file__).resolve().parents[4] / "docs"
READY_MS = 60_000


@pytest.fixture(scope="module")
def tree_server(tmp_path_factory, start_server):
    """Run 1: water->land, 4 robots, 5 generations, switch at 2 over 1 (a compound world at
    2); run 2: the synthetic paper-sized phylogeny."""
    path = tmp_path_factory.mktemp("tree") / "tree.db"
    url = f"sqlite:///{path}"
    started = time.perf_counter()
    softevo(
        "run", "--env", "water-land", "--stiffness", "0.1", "--population", "4", "--generations", "5",
        "--switch-at", "2", "--switch-over", "1", "--workspace", "3,3,3", "--cycles", "2", "--db", url, "-q",
    )  # fmt: skip
    print(f"\ntiny gradual run: {time.perf_counter() - started:.1f} s")
    engine = open_database(url)
    started = time.perf_counter()
    big = synthetic.build(engine, str(path))
    print(f"synthetic 30 x 9000 run: {time.perf_counter() - started:.1f} s")
    engine.dispose()
    return start_server("dashboard", url), big


def open_tree(page, base: str, run_id: int) -> dict:
    page.goto(f"{base}/dashboard/runs/{run_id}")
    page.click("#tree-link")
    page.wait_for_url(f"**/dashboard/runs/{run_id}/tree")
    page.wait_for_function("window.softevoTree !== undefined", timeout=READY_MS)
    return page.evaluate("window.softevoTree")


def shares(image: np.ndarray) -> tuple[float, float]:
    """Shares of land-coloured (orange-brown) and water-coloured (blue) pixels."""
    red, blue = image[..., 0], image[..., 2]
    return float((red - blue > 80).mean()), float((blue - red > 80).mean())


def test_tree_of_a_gradual_transition(tree_server, open_page):
    base, _ = tree_server
    recorded = open_page(base)
    page = recorded.page
    drawn = open_tree(page, base, 1)
    sample = httpx.get(f"{base}/dashboard/api/runs/1/tree").json()
    assert sample["switch_at"] == 2 and sample["switch_over"] == 1 and sample["arrival"] == 3
    assert drawn["drawn"] == len(sample["nodes"]) and drawn["survivors"] == sample["survivors_total"] > 0
    worlds = {n["environment"] for n in drawn["nodes"]}
    assert {"water", "land"} <= worlds and any(">" in w for w in worlds if w)
    final = {
        m["id"] for m in httpx.get(f"{base}/runs/1/front", params={"generation": 4}).json()["individuals"]
    }
    surviving = {n["id"] for n in drawn["nodes"] if n["surviving"]}
    assert final <= surviving
    canvas = page.locator("#tree")
    image = pixels(canvas.screenshot(path=str(DOCS / "phylogeny-tree.png")))
    land, water = shares(image)
    assert land > 0.0005 and water > 0.0005, (land, water)
    assert "switch" in page.locator("#tree-facts").inner_text()
    legend = page.evaluate(
        "[...document.getElementById('tree-legend').childNodes]"
        ".map((n) => n.nodeName === 'SPAN' ? 'swatch' : n.textContent)"
    )
    assert legend == [part for world in sorted(worlds) for part in ("swatch", world)], legend
    assert "[object" not in page.locator("#tree-legend").inner_text()
    node = next(n for n in drawn["nodes"] if n["surviving"] and n["id"] in final)
    box = canvas.bounding_box()
    page.mouse.move(box["x"] + node["x"], box["y"] + node["y"])
    assert f"individual {node['id']}" in page.locator("#tree-hover").inner_text()
    page.mouse.click(box["x"] + node["x"], box["y"] + node["y"])
    page.wait_for_url(f"**/dashboard/individuals/{node['id']}")


def test_tree_of_a_paper_sized_run_stays_bounded(tree_server, open_page):
    base, big = tree_server
    recorded = open_page(base)
    page = recorded.page
    page.add_init_script(RECORD_CANVAS_TEXT)
    started = time.perf_counter()
    drawn = open_tree(page, base, big.run_id)
    seconds = time.perf_counter() - started
    print(f"\n30 x 9000 tree: {drawn['drawn']} nodes of {big.individuals}, ready in {seconds:.1f} s, "
          f"drawn in {drawn['ms']:.0f} ms")  # fmt: skip
    assert 0 < drawn["drawn"] <= 4000 + 600 and drawn["survivors"] > 0
    assert drawn["ms"] < 2000 and seconds < 30
    assert {n["id"] for n in drawn["nodes"] if n["surviving"]} >= set(big.final)
    page.locator("#tree").screenshot(path=str(DOCS / "phylogeny-tree-9000.png"))
    ticks = [int(text) for text in page.evaluate("window.canvasTexts") if text.isdigit()]
    assert ticks and all(tick % 1000 == 0 for tick in ticks), ticks  # round steps, not 5399
