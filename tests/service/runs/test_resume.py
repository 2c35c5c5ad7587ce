"""Acceptance: SIGKILL mid-run (or mid-write), resume, and get the uninterrupted results;
the same for a gradual transition killed inside its switch-over (compound worlds)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import pytest
from sqlalchemy import select

from softevo.service.storage.models import EvaluationRow, RunRow
from tests.service import tinyrun

ROOT = Path(__file__).resolve().parents[3]


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The uninterrupted run (SQLite)."""
    return tinyrun.reference_snapshot(tmp_path_factory.mktemp("ref"))


# generations 0-1 on land, 2-3 in land>water@0.333 / @0.667, 4 in water
GRADUAL = replace(tinyrun.TINY, switch_at=2, switch_over=2)


@pytest.fixture(scope="module")
def gradual_reference(tmp_path_factory):
    """The uninterrupted gradual run (SQLite)."""
    return tinyrun.reference_snapshot(tmp_path_factory.mktemp("gradual"), GRADUAL)


def _python(*args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, *args], cwd=ROOT, stderr=subprocess.PIPE)


def _generation(engine) -> int:
    with engine.connect() as conn:
        return conn.execute(select(RunRow.__table__.c.generation)).scalar_one()


def _environments(engine) -> list[str]:
    table = EvaluationRow.__table__
    with engine.connect() as conn:
        rows = conn.execute(
            select(table.c.generation, table.c.environment).distinct().order_by(table.c.generation)
        )
        return [environment for _, environment in rows]


def _resume_and_compare(engine, reference) -> None:
    tinyrun.run_to_end(engine, 1)
    assert tinyrun.snapshot(engine, 1) == reference


@pytest.mark.parametrize(("mode", "generation"), [("after-commit", 1), ("during-write", 3)])
def test_sigkill_then_resume_is_identical(engine, db_url, reference, mode, generation):
    assert tinyrun.new_run(engine) == 1
    process = _python("-m", "tests.service.killed_run", db_url, mode, str(generation))
    _, stderr = process.communicate(timeout=300)
    assert process.returncode == -signal.SIGKILL, stderr.decode()[-2000:]
    committed = generation if mode == "after-commit" else generation - 1
    assert _generation(engine) == committed
    _resume_and_compare(engine, reference)


def test_gradual_sigkill_inside_the_switch_over_then_resume_is_identical(engine, db_url, gradual_reference):
    mode, generation = "during-write", 3  # generation 2 (land>water@0.333) committed, 3 half written
    assert tinyrun.new_run(engine, GRADUAL) == 1
    process = _python("-m", "tests.service.killed_run", db_url, mode, str(generation))
    _, stderr = process.communicate(timeout=300)
    assert process.returncode == -signal.SIGKILL, stderr.decode()[-2000:]
    assert _generation(engine) == (generation if mode == "after-commit" else generation - 1)
    _resume_and_compare(engine, gradual_reference)
    assert _environments(engine) == ["land", "land", "land>water@0.333", "land>water@0.667", "water"]


@pytest.mark.slow
def test_external_sigkill_of_the_cli_then_resume(engine, db_url, reference):
    assert tinyrun.new_run(engine) == 1
    process = _python("-m", "softevo.service.cli", "resume", "r1", "--db", db_url, "--workers", "0", "-q")
    deadline = time.monotonic() + 300
    while _generation(engine) < 1 and process.poll() is None and time.monotonic() < deadline:
        time.sleep(0.02)
    os.kill(process.pid, signal.SIGKILL)
    process.wait(timeout=60)
    assert _generation(engine) < 4
    _resume_and_compare(engine, reference)
