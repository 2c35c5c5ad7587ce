"""With ``CI=true`` a skipped test is a failed one.

Tests skip where a server or tool they use is missing on a developer's machine (Redis,
PostgreSQL, Chromium, ffmpeg, the Voxelyze reference data). CI installs and starts all of them
(``.ci/run``), so a skip there means a gap in CI, and it must not pass silently.
"""

import os

import pytest

IN_CI = os.environ.get("CI", "").strip().lower() in {"1", "true", "yes"}


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    if IN_CI and report.skipped and not hasattr(report, "wasxfail"):
        reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else str(report.longrepr)
        report.outcome = "failed"
        report.longrepr = f"skipped under CI=true ({reason}): .ci/run must provide what this test needs"
