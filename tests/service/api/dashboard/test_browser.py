"""End-to-end in headless Chromium against a real server: the run page draws its plots, the
individual page replays the robot in 3D (it shows and it moves), pages link through, nothing
is requested outside the server, and the replay frame rate of a 7^3 robot (printed, not
asserted). Skips where Chromium or Playwright is missing (see conftest)."""

from __future__ import annotations

import io
import os

import httpx
import numpy as np
import pytest
from sqlalchemy import create_engine, select

from softevo.service.storage.models import IndividualRow
from tests.service.api.dashboard.chromium import browser_missing

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(browser_missing() is not None, reason=str(browser_missing())),
]

REPLAY_READY_MS = 240_000  # the server simulates the evaluation again for the frames
PLOT_MS = 60_000
SATURATION = 60  # max - min channel: red and cyan voxels, not the grey grid or background
CHANGED = 30  # per-channel difference of a pixel that changed
FPS_SECONDS = 2.0

COUNT_ANIMATION_FRAMES = """seconds => new Promise(resolve => {
  const replay = window.softevoReplay, rendered = replay.renderedFrames;
  let frames = 0;
  const start = performance.now();
  function tick(now) {
    frames += 1;
    if (now - start < seconds * 1000) requestAnimationFrame(tick);
    else resolve({frames, rendered: replay.renderedFrames - rendered, seconds: (now - start) / 1000});
  }
  requestAnimationFrame(tick);
})"""


def pixels(png: bytes) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=np.int16)


def robot_share(image: np.ndarray) -> float:
    """Share of the pixels coloured like a voxel (saturated red or cyan)."""
    return float(((image.max(axis=2) - image.min(axis=2)) > SATURATION).mean())


def changed_share(before: np.ndarray, after: np.ndarray) -> float:
    return float((np.abs(before - after).max(axis=2) > CHANGED).mean())


def open_replay(recorded, base: str, individual_id: int):
    page = recorded.page
    page.goto(f"{base}/dashboard/individuals/{individual_id}")
    page.wait_for_function("window.softevoReplay !== undefined", timeout=REPLAY_READY_MS)
    page.wait_for_selector("#play:not([disabled])")
    return page


def test_run_page_draws_fitness_and_front(dashboard_url, tiny_db, open_page):
    recorded = open_page(dashboard_url)
    page = recorded.page
    page.goto(f"{dashboard_url}/dashboard/")
    page.click(f"a[href='/dashboard/runs/{tiny_db.run_id}']")
    page.wait_for_url(f"**/dashboard/runs/{tiny_db.run_id}")
    page.wait_for_selector("#fitness svg.main-svg .scatterlayer .trace", timeout=PLOT_MS)
    assert page.locator("#fitness .scatterlayer .trace").count() == 2  # best and mean
    assert page.locator("#fitness .scatterlayer .trace .points path").count() >= 4  # 2 generations x 2
    page.wait_for_selector("#front .scatterlayer .trace .points path", timeout=PLOT_MS)
    front = httpx.get(f"{dashboard_url}/runs/{tiny_db.run_id}/front").json()["individuals"]
    assert page.locator("#front .scatterlayer .trace .points path").count() == len(front)
    assert page.locator("#front-table tbody tr").count() == len(front)
    assert "finished" in page.locator("#run-status").inner_text()
    first = httpx.get(f"{dashboard_url}/runs/{tiny_db.run_id}/front?generation=0").json()["individuals"]
    page.locator("#front-generation").fill("0")
    page.wait_for_function("document.getElementById('front-label').textContent.startsWith('generation 0 ')")
    page.wait_for_function(f"document.querySelectorAll('#front-table tbody tr').length === {len(first)}")
    assert page.locator("#front .scatterlayer .trace .points path").count() == len(first)
    assert not page.locator("#front-latest").is_checked()


def test_experiments_page_shows_the_plan_of_its_form(dashboard_url, open_page):
    page = open_page(dashboard_url).page
    page.goto(f"{dashboard_url}/dashboard/")
    page.wait_for_selector("#plan table.kv", timeout=PLOT_MS)  # the form's default: paper, tiny
    text = page.locator("#plan").inner_text()
    for shown in ("wall time", "hours", "core-hours", "database", "GB", "utilisation"):
        assert shown in text
    page.locator("#plan-cores").fill("4")
    page.click("#plan-form button")
    page.wait_for_selector("#plan table.kv", timeout=PLOT_MS)
    assert "runs" in page.locator("#plan").inner_text()


def test_clicking_a_front_point_opens_the_individual(dashboard_url, tiny_db, open_page):
    page = open_page(dashboard_url).page
    page.goto(f"{dashboard_url}/dashboard/runs/{tiny_db.run_id}")
    point = page.locator("#front .scatterlayer .trace .points path").first
    point.wait_for(timeout=PLOT_MS)
    point.click(force=True)  # plotly's drag layer lies above the points and takes the click
    page.wait_for_url("**/dashboard/individuals/*")
    page.wait_for_selector("#objectives table")


def test_replay_shows_the_robot_moving(dashboard_url, tiny_db, open_page, tmp_path):
    best = httpx.get(f"{dashboard_url}/runs/{tiny_db.run_id}").json()["best"]["individual_id"]
    page = open_replay(open_page(dashboard_url), dashboard_url, best)
    canvas = page.locator("#viewer canvas")
    page.click("#play")
    assert page.locator("#play").inner_text() == "Pause"
    page.wait_for_timeout(300)
    first = canvas.screenshot(path=str(tmp_path / "replay-1.png"))
    page.wait_for_timeout(500)
    second = canvas.screenshot(path=str(tmp_path / "replay-2.png"))
    page.screenshot(path=str(tmp_path / "individual-page.png"), full_page=True)
    before, after = pixels(first), pixels(second)
    assert robot_share(before) > 0.005, "no voxel on the canvas"
    assert robot_share(after) > 0.005, "no voxel on the canvas"
    assert changed_share(before, after) > 0.002, "the robot did not move between the screenshots"
    assert "t = " in page.locator("#clock").inner_text()
    page.click("#play")
    assert page.locator("#play").inner_text() == "Play"


def test_individual_page_links_to_its_parent(dashboard_url, tiny_db, open_page):
    child = _an_individual_with_a_parent(tiny_db.url, tiny_db.run_id)
    recorded = open_page(dashboard_url)
    page = recorded.page
    page.goto(f"{dashboard_url}/dashboard/individuals/{child['id']}")
    page.wait_for_selector("#parent-link")
    page.wait_for_selector("#objectives table")
    assert page.locator("#descriptors table tr").count() >= 3
    assert "CPPN" in page.locator("#genome").inner_text()
    page.click("#parent-link")
    page.wait_for_url(f"**/dashboard/individuals/{child['parent_id']}")
    page.wait_for_selector("#lineage ol li")


def _an_individual_with_a_parent(url: str, run_id: int) -> dict:
    """A child born in generation 1 of the tiny run (AFPO breeds every generation)."""
    table = IndividualRow.__table__
    engine = create_engine(url)
    with engine.connect() as conn:
        row = conn.execute(
            select(table.c.id, table.c.parent_id)
            .where(table.c.run_id == run_id, table.c.parent_id.is_not(None))
            .order_by(table.c.id)
            .limit(1)
        ).one()
    engine.dispose()
    return {"id": row.id, "parent_id": row.parent_id}


def test_replay_frame_rate_of_a_7x7x7_robot(dashboard_url, tiny_db, open_page, capsys):
    page = open_replay(open_page(dashboard_url), dashboard_url, tiny_db.block_id)
    assert "343 voxels" in page.locator("#replay-environment").inner_text()
    renderer = page.evaluate(
        "() => { const gl = window.softevoReplay.renderer.getContext();"
        " const info = gl.getExtension('WEBGL_debug_renderer_info');"
        " return info ? gl.getParameter(info.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER); }"
    )
    size = page.evaluate(
        "() => { const c = window.softevoReplay.renderer.domElement; return [c.width, c.height]; }"
    )
    page.click("#play")
    page.wait_for_timeout(500)
    measured = page.evaluate(COUNT_ANIMATION_FRAMES, FPS_SECONDS)
    fps = measured["frames"] / measured["seconds"]
    rendered = measured["rendered"] / measured["seconds"]
    assert measured["rendered"] > 0, "the replay rendered nothing while playing"
    with capsys.disabled():
        print(
            f"\nreplay of a 7^3 robot (343 voxels), canvas {size[0]}x{size[1]}, {renderer}: "
            f"{fps:.1f} animation frames/s, {rendered:.1f} rendered frames/s "
            f"over {measured['seconds']:.1f} s ({os.cpu_count()} CPUs)"
        )
