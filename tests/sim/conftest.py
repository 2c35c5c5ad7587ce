"""Physics-test plumbing: list the measured agreement figures at the end of the run."""

from __future__ import annotations

from tests.sim._support import AGREEMENT, AGREEMENT_PATH, _fmt


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    if not AGREEMENT:
        return
    terminalreporter.section("softevo sim: measured agreement")
    for name, figures in AGREEMENT.items():
        text = ", ".join(f"{k}={_fmt(v)}" for k, v in figures.items())
        terminalreporter.write_line(f"{name}: {text}")
    terminalreporter.write_line(f"(also in {AGREEMENT_PATH})")
