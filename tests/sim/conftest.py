"""Physics-test plumbing: the precision under test, and the measured agreement figures listed
at the end of the run."""

from __future__ import annotations

import pytest

from softevo.sim.models import PRECISIONS
from tests.sim import _support
from tests.sim._support import AGREEMENT, AGREEMENT_PATH, _fmt


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    if not AGREEMENT:
        return
    terminalreporter.section("softevo sim: measured agreement")
    for name, figures in AGREEMENT.items():
        text = ", ".join(f"{k}={_fmt(v)}" for k, v in figures.items())
        terminalreporter.write_line(f"{name}: {text}")
    terminalreporter.write_line(f"(also in {AGREEMENT_PATH})")


@pytest.fixture(params=PRECISIONS)
def precision(request, monkeypatch):
    """Each precision in turn as the one under test (``_support.PRECISION``): a module that
    wants its tests run in both says ``pytestmark = pytest.mark.usefixtures("precision")``."""
    monkeypatch.setattr(_support, "PRECISION", request.param)
    return request.param
