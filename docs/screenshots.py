"""Screenshot of the dashboard's experiment page, for docs/ and the README.

Usage: python docs/screenshots.py --db URL --experiment REF [--out docs/experiment-page.png]
                                  [--width 1400] [--timeout 900]

Starts ``softevo dashboard`` on the database (read-only, a free loopback port), opens
``/dashboard/experiments/{id}`` in headless Chromium (Debian's ``chromium`` through the
``playwright`` Python package, as the browser tests do), waits until the page has drawn
the comparison (``GET /experiments/{id}/analysis`` is computed on the first request: on a
paper-sized study that takes a while, hence ``--timeout`` seconds), and saves the whole page
as a PNG. ``REF`` is an experiment id, ``e3``, ``latest`` or a name
(``service.storage.experiments.resolve_experiment``). Prints the PNG's path and size.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
from pathlib import Path

from softevo.service.api.loopback import free_port, wait_healthy

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                  "--disable-component-update", "--no-first-run"]  # fmt: skip
START_S = 60
DEFAULT_OUT = Path(__file__).resolve().parent / "experiment-page.png"


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


def screenshot(base: str, experiment: int, out: Path, width: int, timeout_s: float) -> None:
    """Open the experiment page in headless Chromium and save it whole as ``out``."""
    from playwright.sync_api import sync_playwright

    executable = CHROMIUM if Path(CHROMIUM).exists() else shutil.which("chromium")
    if executable is None:
        raise SystemExit("chromium is not installed (apt-get install chromium)")
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=executable, args=CHROMIUM_FLAGS)
        try:
            page = browser.new_page(viewport={"width": width, "height": 900}, device_scale_factor=1)
            page.goto(f"{base}/dashboard/experiments/{experiment}")
            page.wait_for_selector("body[data-analysis=ready]", timeout=timeout_s * 1000)
            page.wait_for_timeout(1500)  # plotly's last resize
            out.parent.mkdir(parents=True, exist_ok=True)
            page.screenshot(path=str(out), full_page=True)
        finally:
            browser.close()


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--db", default=os.environ.get("SOFTEVO_DB"), help="SQLAlchemy URL of the database")
    parser.add_argument("--experiment", default="latest", help="id, eN, latest or name (default latest)")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="PNG to write")
    parser.add_argument("--width", type=int, default=1400, help="viewport width in CSS pixels")
    parser.add_argument("--timeout", type=float, default=900, help="seconds to wait for the page")
    args = parser.parse_args(argv)
    if not args.db:
        raise SystemExit("give --db URL (or set SOFTEVO_DB)")
    from softevo.errors import UserError

    try:
        experiment = experiment_id(args.db, args.experiment)
    except UserError as exc:
        raise SystemExit(f"error: {exc}") from exc
    process, base = start_dashboard(args.db)
    try:
        screenshot(base, experiment, args.out, args.width, args.timeout)
    finally:
        process.terminate()
        process.wait(timeout=20)
    print(f"{args.out} ({args.out.stat().st_size} bytes): experiment {experiment}")


if __name__ == "__main__":
    main()
