"""The same pages on the distributed service's entry point, ``softevo serve`` (coordinator
on, local executor): the run page draws its plot, and the experiments page follows a run
submitted through the API from pending to finished without a reload."""

from __future__ import annotations

import shutil

import httpx
import pytest

from tests.service.api.dashboard.chromium import browser_missing

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(browser_missing() is not None, reason=str(browser_missing())),
]

LIVE_RUN_MS = 300_000
EXPERIMENT = {
    "name": "live",
    "treatments": [
        {
            "name": "live land",
            "environment": "land",
            "stiffness_mpa": 1.0,
            "population": 2,
            "generations": 2,
            "workspace": [3, 3, 3],
            "cycles": 1,
        }
    ],
}


@pytest.fixture(scope="module")
def serve_url(tiny_db, start_server, tmp_path_factory) -> str:
    """``softevo serve`` on a copy of the tiny database (its runs get written to)."""
    copy = tmp_path_factory.mktemp("serve") / "tiny.db"
    shutil.copy(tiny_db.path, copy)
    return start_server("serve", f"sqlite:///{copy}")


def test_run_page_on_softevo_serve(serve_url, tiny_db, open_page):
    assert httpx.get(f"{serve_url}/health").json()["coordinator"] is True
    page = open_page(serve_url).page
    page.goto(f"{serve_url}/dashboard/runs/{tiny_db.run_id}")
    page.wait_for_selector("#fitness .scatterlayer .trace .points path", timeout=60_000)
    assert page.locator("#fitness .scatterlayer .trace").count() == 2


def test_experiments_page_follows_a_live_run(serve_url, open_page):
    created = httpx.post(f"{serve_url}/experiments", json=EXPERIMENT, timeout=30)
    assert created.status_code == 201, created.text
    experiment_id, (run_id,) = created.json()["id"], created.json()["runs"]
    recorded = open_page(serve_url)
    page = recorded.page
    navigations = []
    page.on("framenavigated", lambda frame: navigations.append(frame.url))
    page.goto(f"{serve_url}/dashboard/")
    row = page.locator(f"#experiment-{experiment_id} tbody tr")
    row.wait_for()
    assert row.locator(".badge").inner_text() in ("pending", "running")
    page.wait_for_function(
        f"document.querySelector('#experiment-{experiment_id} tbody .badge').textContent === 'finished'",
        timeout=LIVE_RUN_MS,
    )
    assert row.locator("td").nth(5).inner_text() == "2/2"
    assert len(navigations) == 1, "the page reloaded instead of polling"
    assert httpx.get(f"{serve_url}/runs/{run_id}").json()["status"] == "finished"
