"""Fixtures of the dashboard tests: a real tiny run in SQLite (made with the CLI), a real
uvicorn server on loopback (``softevo dashboard`` or ``softevo serve``), headless Chromium.

Browser tests skip (with the reason) where Debian's ``chromium`` or the ``playwright`` Python
package is missing; install them with
``apt-get install -y --no-install-recommends chromium chromium-driver`` and
``pip install playwright`` (never ``playwright install``: it downloads a browser).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
from sqlalchemy import create_engine, select, update

from softevo.service.storage.models import IndividualRow
from tests.service.api.dashboard.block import WORKSPACE, block_genome
from tests.service.api.dashboard.chromium import CHROMIUM, CHROMIUM_FLAGS, browser_missing
from tests.support import free_port, softevo_process, wait_healthy

SERVER_START_S = 60
CLI_TIMEOUT_S = 600


@dataclass(frozen=True)
class TinyDatabase:
    path: Path
    url: str
    run_id: int  # the 4x4x4 run, 2 generations
    block_id: int  # an individual of the 7x7x7 run whose genome is the full block


def softevo(*args: str, env: dict | None = None) -> subprocess.CompletedProcess:
    """Run the CLI in a subprocess (as a user would), failing the test on a non-zero exit."""
    done = softevo_process(*args, env=env, timeout=CLI_TIMEOUT_S)
    assert done.returncode == 0, f"softevo {' '.join(args)} failed:\n{done.stdout}\n{done.stderr}"
    return done


def _tiny_run(url: str, workspace: str, population: int, generations: int) -> None:
    softevo(
        "run", "--env", "land", "--stiffness", "1", "--population", str(population),
        "--generations", str(generations), "--workspace", workspace, "--cycles", "2", "--db", url,
    )  # fmt: skip


def _install_block(url: str, run_id: int) -> int:
    """Give the first individual of ``run_id`` (a 7x7x7 run) the full-block genome: the
    replay re-simulates from the genome, so its page replays a 343-voxel robot."""
    engine = create_engine(url)
    table = IndividualRow.__table__
    with engine.begin() as conn:
        individual_id = conn.execute(
            select(table.c.id).where(table.c.run_id == run_id).order_by(table.c.id).limit(1)
        ).scalar_one()
        conn.execute(update(table).where(table.c.id == individual_id).values(genome=block_genome()))
    engine.dispose()
    return individual_id


@pytest.fixture(scope="session")
def tiny_db(tmp_path_factory) -> TinyDatabase:
    """Run 1: land, 1 MPa, 4 robots, 2 generations in 4x4x4, 2 cycles (the CLI's own run).
    Run 2: 2 robots, 1 generation in 7x7x7, one of them replaced by the full block."""
    path = tmp_path_factory.mktemp("dashboard") / "tiny.db"
    url = f"sqlite:///{path}"
    _tiny_run(url, "4,4,4", population=4, generations=2)
    _tiny_run(url, ",".join(map(str, WORKSPACE)), population=2, generations=1)
    return TinyDatabase(path, url, run_id=1, block_id=_install_block(url, run_id=2))


@pytest.fixture(scope="session")
def start_server():
    """``start_server(command, db_url) -> base URL``: the CLI command serving on a free
    loopback port; every server is stopped at the end of the session."""
    processes: list[subprocess.Popen] = []

    def start(command: str, url: str, env: dict | None = None) -> str:
        port = free_port()
        process = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "softevo.service.cli",
                command,
                "--db",
                url,
                "--host",
                "127.0.0.1",
                "--port",
                str(port),
            ],
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            env={**os.environ, "SOFTEVO_WORKERS": "1", **(env or {})},
        )
        processes.append(process)
        base = f"http://127.0.0.1:{port}"
        wait_healthy(base, process, SERVER_START_S)
        return base

    yield start
    for process in processes:
        process.terminate()
    for process in processes:
        try:
            process.wait(timeout=20)
        except subprocess.TimeoutExpired:
            process.kill()


@pytest.fixture(scope="session")
def dashboard_url(tiny_db, start_server) -> str:
    """Base URL of ``softevo dashboard`` on the tiny database."""
    return start_server("dashboard", tiny_db.url)


@pytest.fixture(scope="session")
def browser() -> Iterator:
    reason = browser_missing()
    if reason:
        pytest.skip(reason)
    from playwright.sync_api import sync_playwright

    executable = CHROMIUM if Path(CHROMIUM).exists() else shutil.which("chromium")
    with sync_playwright() as playwright:
        chromium = playwright.chromium.launch(executable_path=executable, args=CHROMIUM_FLAGS)
        yield chromium
        chromium.close()


class RecordedPage:
    """A Playwright page that records every request and page error."""

    def __init__(self, page) -> None:
        self.page = page
        self.requests: list[str] = []
        self.errors: list[str] = []
        page.on("request", lambda request: self.requests.append(request.url))
        page.on("pageerror", lambda error: self.errors.append(str(error)))

    def outside(self, origin: str) -> list[str]:
        """Requested URLs not on ``origin``."""
        return [url for url in self.requests if not url.startswith(origin + "/")]


@pytest.fixture
def open_page(browser):
    """``open_page(origin) -> RecordedPage``; at teardown asserts the page requested
    nothing outside ``origin`` and raised no JavaScript error."""
    opened: list[tuple[RecordedPage, str, object]] = []

    def open_(origin: str) -> RecordedPage:
        context = browser.new_context(viewport={"width": 1280, "height": 900})
        recorded = RecordedPage(context.new_page())
        opened.append((recorded, origin, context))
        return recorded

    yield open_
    for recorded, origin, context in opened:
        context.close()
        assert recorded.outside(origin) == [], "requests outside the server"
        assert recorded.errors == [], "JavaScript errors"


@dataclass(frozen=True)
class ComparedDatabase:
    url: str
    experiment_id: int  # tests.service.api.dashboard.compared: 4 treatments x 3 runs
    empty_id: int  # an experiment without runs


@pytest.fixture(scope="session")
def compared_db(tmp_path_factory) -> ComparedDatabase:
    """SQLite with the experiment of ``tests.service.api.dashboard.compared`` (written directly)."""
    from softevo.service.storage import open_database
    from tests.service.api.dashboard import compared

    path = tmp_path_factory.mktemp("compared") / "compared.db"
    engine = open_database(f"sqlite:///{path}")
    experiment_id = compared.build(engine)
    engine.dispose()
    return ComparedDatabase(f"sqlite:///{path}", experiment_id, experiment_id + 1)


@pytest.fixture(scope="session")
def compared_url(compared_db, start_server) -> str:
    """Base URL of ``softevo dashboard`` on the compared experiment."""
    return start_server("dashboard", compared_db.url)
