"""A world added through the registry alone (``sim.worlds.register``) is accepted and shown
everywhere: ``softevo run --env moon`` evolves in it (real SQLite), the REST schema's enums,
``GET /worlds``, the dashboard's pages (the API in this process, uvicorn on loopback, real
HTTP) and the report list it. The ``moon`` fixture removes it again, so other tests (and
other xdist workers, each its own process) never see it."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator

import httpx
import pytest
import sqlalchemy
import uvicorn

from softevo.evolution import environments
from softevo.sim import parse_scene
from tests.service.cli.test_cli_runs import TINY
from tests.support import free_port, softevo

MOON = environments.World("moon", gravity=1.62, floor=True, drag=False, colour="#8a8f98", label="on the moon")


@pytest.fixture
def moon() -> Iterator[environments.World]:
    world = environments.register(MOON)
    try:
        yield world
    finally:
        environments.unregister(world.name)


@pytest.fixture
def moon_db(moon, capsys, tmp_path) -> str:
    db = f"sqlite:///{tmp_path / 'moon.db'}"
    code, out, err = softevo(capsys, "run", "--env", "moon", "--stiffness", "1", *TINY, "--db", db)
    assert code == 0, err
    assert "finished" in out
    assert evaluation_errors(db) == [None]
    return db


def evaluation_errors(db: str) -> list:
    with sqlalchemy.create_engine(db).connect() as conn:
        return conn.execute(sqlalchemy.text("SELECT DISTINCT error FROM evaluations")).scalars().all()


@pytest.fixture
def api(moon_db) -> Iterator[str]:
    """The API and dashboard of ``moon_db`` served from this process (where moon is
    registered) on a loopback port; the coordinator off."""
    from softevo.service.api.app import create_app
    from softevo.service.settings import Settings

    port = free_port()
    app = create_app(Settings(db=moon_db, coordinator=False, host="127.0.0.1", port=port))
    server = uvicorn.Server(uvicorn.Config(app, host="127.0.0.1", port=port, log_level="warning"))
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    base = f"http://127.0.0.1:{port}"
    deadline = time.monotonic() + 30
    while not server.started:
        assert time.monotonic() < deadline and thread.is_alive(), "the server did not start"
        time.sleep(0.05)
    try:
        yield base
    finally:
        server.should_exit = True
        thread.join(10)


def test_a_registered_world_is_a_scene_and_a_treatment_environment(moon):
    assert "moon" in environments.environments() and "land-moon" in environments.environments()
    assert environments.transition("moon-water") == ("moon", "water")
    assert moon.kind == environments.LAND.name
    assert moon.distance == "horizontal" and moon.settle_seconds == 0.5
    environment = parse_scene({"body": [[[1]]], "environment": moon.scene_environment()}).environment
    assert (environment.kind, environment.gravity) == (environments.LAND.name, 1.62)


def test_spawned_evaluation_processes_know_the_registered_world(moon, capsys, tmp_path):
    """``--workers 1``: the evaluations run in a spawned pool process, which registers the
    parent's added worlds (``worker.evaluate.init_pool_process``)."""
    args = [a for a in TINY if a not in ("--workers", "0")]
    db = f"sqlite:///{tmp_path / 'pool.db'}"
    code, out, err = softevo(capsys, "run", "--env", "moon", "--stiffness", "1", *args, "--workers", "1",
                             "--db", db)
    assert code == 0, err
    assert "finished" in out
    assert evaluation_errors(db) == [None]


def test_the_registration_is_undone():
    assert "moon" not in environments.names()
    assert "moon" not in environments.environments()


def test_softevo_run_the_api_the_dashboard_and_the_report_show_moon(moon_db, api, capsys, tmp_path):
    # the run evolved in moon, with moon's gravity
    runs = httpx.get(f"{api}/runs").json()
    assert [run["environment"] for run in runs] == ["moon"]
    run = httpx.get(f"{api}/runs/{runs[0]['id']}").json()
    best = httpx.get(f"{api}/runs/{run['id']}/best").json()
    assert best, run
    assert {b["environment"] for b in best} == {"moon"}
    individual = best[0]["individual_id"]
    stored = httpx.get(f"{api}/individuals/{individual}").json()
    assert {e["environment"] for e in stored["evaluations"]} == {"moon"}

    # the REST schema's enums
    schema = httpx.get(f"{api}/openapi.json").json()["components"]["schemas"]
    enum = schema["TreatmentIn"]["properties"]["environment"]["enum"]
    assert {"moon", "land-moon", "moon-water"} <= set(enum)
    listed = {w["name"]: w for w in httpx.get(f"{api}/worlds").json()}
    assert listed["moon"]["gravity"] == 1.62 and listed["moon"]["colour"] == "#8a8f98"
    assert listed["moon"]["kind"] == environments.LAND.name

    # the body endpoint takes moon as a world
    body = httpx.get(f"{api}/dashboard/api/individuals/{individual}/body", params={"environment": "moon"})
    assert body.status_code == 200, body.text
    bad = httpx.get(f"{api}/dashboard/api/individuals/{individual}/body", params={"environment": "mars"})
    assert bad.status_code == 422

    # the dashboard's pages carry the registry (colours) the JS draws worlds with
    page = httpx.get(f"{api}/dashboard/runs/{run['id']}")
    assert page.status_code == 200 and "#8a8f98" in page.text and "moon" in page.text

    # the report
    code, _, err = softevo(capsys, "report", "latest", "--out", str(tmp_path / "r"), "--db", moon_db,
                           "--no-animation", "-q")
    assert code == 0, err
    markdown = (tmp_path / "r" / "report.md").read_text(encoding="utf-8")
    assert "moon" in markdown and "on the moon" in markdown
