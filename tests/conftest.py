"""With ``CI=true`` a skipped test is a failed one.

Tests skip where a server or tool they use is missing on a developer's machine (Redis,
PostgreSQL, Chromium, ffmpeg, the Voxelyze reference data). CI installs and starts all of them
(``.ci/run``), so a skip there means a gap in CI, and it must not pass silently.
"""

import os
import re
import subprocess
import sys

import pytest

IN_CI = os.environ.get("CI", "").strip().lower() in {"1", "true", "yes"}

# The cuda engine's tests run on numba-cuda's simulator unless a GPU is asked for
# (``SOFTEVO_CUDA_TEST_DEVICE``, tests/sim/test_cuda_engine.py); numba-cuda reads this once,
# at its import, so it is set before any test module imports it.
if "SOFTEVO_CUDA_TEST_DEVICE" not in os.environ:
    os.environ.setdefault("NUMBA_ENABLE_CUDASIM", "1")


def _own_servers_per_worker() -> None:
    """Under ``pytest -n N`` (pytest-xdist) each worker process gets a Redis database and a
    PostgreSQL database of its own on the shared servers, so that one worker's wipe never
    meets another's data: worker k uses Redis database (d - k) mod 16 of
    ``$SOFTEVO_TEST_REDIS_URL``'s d, and ``<name>_gw<k>`` beside ``$SOFTEVO_TEST_POSTGRES``'s
    database (created here when missing). Worker 0, and a run without -n, use them as given."""
    worker = os.environ.get("PYTEST_XDIST_WORKER", "")
    index = int(worker[2:]) if re.fullmatch(r"gw\d+", worker) else 0
    if index == 0:
        return
    redis_url = os.environ.get("SOFTEVO_TEST_REDIS_URL")
    if redis_url:
        match = re.fullmatch(r"(redis://[^/]+)(?:/(\d+))?", redis_url)
        if match:
            database = (int(match.group(2) or 0) - index) % 16
            os.environ["SOFTEVO_TEST_REDIS_URL"] = f"{match.group(1)}/{database}"
    postgres_url = os.environ.get("SOFTEVO_TEST_POSTGRES")
    if postgres_url:
        from sqlalchemy import create_engine, text
        from sqlalchemy.engine import make_url

        url = make_url(postgres_url)
        own = f"{url.database}_gw{index}"
        server = create_engine(url.set(database="postgres"), isolation_level="AUTOCOMMIT")
        with server.connect() as conn:
            exists = conn.execute(text("SELECT 1 FROM pg_database WHERE datname = :name"), {"name": own})
            if exists.first() is None:
                conn.execute(text(f'CREATE DATABASE "{own}"'))
        server.dispose()
        os.environ["SOFTEVO_TEST_POSTGRES"] = url.set(database=own).render_as_string(hide_password=False)


_own_servers_per_worker()


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    if IN_CI and report.skipped and not hasattr(report, "wasxfail"):
        reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else str(report.longrepr)
        report.outcome = "failed"
        report.longrepr = f"skipped under CI=true ({reason}): .ci/run must provide what this test needs"


# Under ``pytest -n N`` numba's on-disk cache of the simulator's kernels is filled once, by the
# controller, before the workers start: with a cold cache every worker and every ``softevo``
# subprocess a test starts compiled the same kernels at once (1-2 min of a core each; one
# fixture took 217 s instead of 3 in CI). One subprocess per precision, in parallel; the
# energy audit's kernels with each. A failure here is left to the tests to report.
WARM_UP = """
import sys
from softevo.worker.evaluate import warm_up
from softevo.worker.physics import energy_audit
precision = sys.argv[1]
if precision == "float64":
    warm_up()  # the float64 kernels, the water mesh's and the shape descriptors
body = [[[2]], [[1]]]
for model, world in (("voxelyze-2", "land"), ("voxcad-land-water", "water")):
    scene = {"body": body, "duration": {"cycles": 1}, "model": model,
             "environment": {"kind": world}, "model_options": {"precision": precision}}
    energy_audit(scene)
"""


def pytest_configure(config):
    if os.environ.get("PYTEST_XDIST_WORKER") or not getattr(config.option, "numprocesses", None):
        return
    warming = [subprocess.Popen([sys.executable, "-c", WARM_UP, precision],
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
               for precision in ("float64", "mixed")]
    for process in warming:
        process.wait()
