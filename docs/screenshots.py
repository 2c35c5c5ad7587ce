"""Screenshots of the dashboard for docs/ and the README: the experiment page, a transition
run's page and an individual's page.

Usage: python docs/screenshots.py [--db URL --experiment REF] [--out-dir docs]
                                  [--width 1400] [--timeout 900]

Without ``--db`` it first builds a small real database in a temporary folder, as a user
would: ``softevo experiment paper --scale tiny --repetitions 3`` of four treatments (land
S3, water S3 and the two transitions between them; a few minutes on 2 cores). It then starts
``softevo dashboard`` on the database (read-only, a free loopback port), opens the pages in
headless Chromium (Debian's ``chromium`` through the ``playwright`` Python package, as the
browser tests do) and saves each whole page as a PNG in ``--out-dir``:

- ``experiment-page.png``: ``/dashboard/experiments/{id}`` once it has drawn the comparison
  (``GET /experiments/{id}/analysis`` is computed on the first request: on a paper-sized
  study that takes a while, hence ``--timeout`` seconds);
- ``transition-run-page.png``: the page of the experiment's first transition run (its first
  run if it has none);
- ``individual-page.png``: that run's best individual in its last world, as the run page
  links it, once its replay is ready.

``REF`` is an experiment id, ``e3``, ``latest`` or a name
(``service.storage.experiments.resolve_experiment``). Prints each PNG's path and size.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import urllib.request
from pathlib import Path

from softevo.service.api.loopback import free_port, wait_healthy

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                  "--disable-component-update", "--no-first-run"]  # fmt: skip
START_S = 60
BUILD_S = 1800
DOCS = Path(__file__).resolve().parent
PAGES = ("experiment-page.png", "transition-run-page.png", "individual-page.png")
BUILT_TREATMENTS = "land S3,water S3,land-water S3,water-land S3"
SETTLE_MS = 1500  # plotly's last resize


def build_database(folder: Path) -> str:
    """A small real experiment made with the CLI: the paper's grid at the tiny scale, three
    repetitions of land S3, water S3 and the two transitions. Returns its URL."""
    url = f"sqlite:///{folder / 'screenshots.db'}"
    command = [sys.executable, "-m", "softevo.service.cli", "experiment", "paper", "--scale", "tiny",
               "--repetitions", "3", "--treatments", BUILT_TREATMENTS, "--name", "screenshots",
               "--db", url, "-q"]  # fmt: skip
    done = subprocess.run(command, capture_output=True, text=True, timeout=BUILD_S)
    if done.returncode != 0:
        raise SystemExit(f"softevo experiment failed: {done.stderr.strip()}")
    return url


def experiment_id(db: str, reference: str) -> int:
    from softevo.service.storage import open_database
    from softevo.service.storage.experiments import resolve_experiment

    engine = open_database(db, create=False)
    try:
        with engine.connect() as conn:
            return resolve_experiment(conn, reference)
    finally:
        engine.dispose()


def start_dashboard(db: str) -> tuple[subprocess.Popen, str]:
    """``softevo dashboard`` on a free loopback port, once it answers ``/health``."""
    port = free_port()
    command = [sys.executable, "-m", "softevo.service.cli", "dashboard", "--db", db,
               "--host", "127.0.0.1", "--port", str(port)]  # fmt: skip
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    base = f"http://127.0.0.1:{port}"
    try:
        wait_healthy(base, process, START_S)
    except RuntimeError as exc:
        process.terminate()
        raise SystemExit(f"softevo dashboard: {exc}") from None
    return process, base


def get_json(base: str, path: str):
    with urllib.request.urlopen(f"{base}{path}", timeout=60) as answer:
        return json.load(answer)


def transition_run(base: str, experiment: int) -> dict:
    """The experiment's first run whose treatment switches world (else its first run)."""
    runs = get_json(base, f"/experiments/{experiment}?runs_limit=1000")["runs"]
    if not runs:
        raise SystemExit(f"experiment {experiment} has no run")
    details = (get_json(base, f"/runs/{run['id']}") for run in runs)
    first = None
    for run in details:
        first = first or run
        if "-" in run["treatment"]["settings"]["environment"]:  # land-water, water-land
            return run
    return first


def screenshots(base: str, experiment: int, out_dir: Path, width: int, timeout_s: float) -> list[Path]:
    """The three pages, each saved whole in ``out_dir``."""
    from playwright.sync_api import sync_playwright

    executable = CHROMIUM if Path(CHROMIUM).exists() else shutil.which("chromium")
    if executable is None:
        raise SystemExit("chromium is not installed (apt-get install chromium)")
    run = transition_run(base, experiment)
    best = run["best"]
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = [out_dir / name for name in PAGES]
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=executable, args=CHROMIUM_FLAGS)
        try:
            page = browser.new_page(viewport={"width": width, "height": 900}, device_scale_factor=1)
            page.goto(f"{base}/dashboard/experiments/{experiment}")
            page.wait_for_selector("body[data-analysis=ready]", timeout=timeout_s * 1000)
            page.wait_for_timeout(SETTLE_MS)
            page.screenshot(path=str(paths[0]), full_page=True)

            page.goto(f"{base}/dashboard/runs/{run['id']}")
            page.wait_for_selector("#front .scatterlayer .trace", timeout=timeout_s * 1000)
            page.wait_for_selector("#fitness .scatterlayer .trace", timeout=timeout_s * 1000)
            page.wait_for_timeout(SETTLE_MS)
            page.screenshot(path=str(paths[1]), full_page=True)

            if best is not None:
                page.goto(
                    f"{base}/dashboard/individuals/{best['individual_id']}?environment={best['environment']}"
                )
                page.wait_for_function(
                    "window.softevoReplay !== undefined"
                    " || document.getElementById('viewer-status').classList.contains('error')",
                    timeout=timeout_s * 1000,
                )
                page.evaluate("window.softevoReplay && window.softevoReplay.seek(0.5)")  # mid-stride
                page.wait_for_timeout(SETTLE_MS)
                page.screenshot(path=str(paths[2]), full_page=True)
        finally:
            browser.close()
    return [path for path in paths if path.exists()]


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--db", default=os.environ.get("SOFTEVO_DB"),
                        help="SQLAlchemy URL of the database (default: build a small one)")  # fmt: skip
    parser.add_argument("--experiment", default="latest", help="id, eN, latest or name (default latest)")
    parser.add_argument("--out-dir", type=Path, default=DOCS, help="folder of the PNGs (default docs/)")
    parser.add_argument("--width", type=int, default=1400, help="viewport width in CSS pixels")
    parser.add_argument("--timeout", type=float, default=900, help="seconds to wait for a page")
    args = parser.parse_args(argv)
    from softevo.errors import UserError

    with tempfile.TemporaryDirectory(prefix="softevo-screenshots-") as folder:
        db = args.db or build_database(Path(folder))
        try:
            experiment = experiment_id(db, args.experiment)
        except UserError as exc:
            raise SystemExit(f"error: {exc}") from exc
        process, base = start_dashboard(db)
        try:
            written = screenshots(base, experiment, args.out_dir, args.width, args.timeout)
        finally:
            process.terminate()
            process.wait(timeout=20)
    for path in written:
        print(f"{path} ({path.stat().st_size} bytes): experiment {experiment}")


if __name__ == "__main__":
    main()
