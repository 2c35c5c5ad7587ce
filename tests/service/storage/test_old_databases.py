"""Stored runs from before issue 48 still load: a database written by 24e95c0 (the layout
before the domain moved into evolution/ and the evaluation got its carrier; its algorithm
states hold the flat config) is read, reported, exported and resumed by this version."""

from __future__ import annotations

import shutil
from pathlib import Path

from sqlalchemy import create_engine, select, update

from softevo.evolution.algorithm import Evolution
from softevo.service.storage.models import GenerationRow, RunRow
from tests.support import softevo_process

ROOT = Path(__file__).resolve().parents[3]
OLD = Path(__file__).parent / "data" / "softevo-24e95c0.db"  # land-water, 4 robots, 3 generations


def copy_of_old(tmp_path: Path) -> str:
    shutil.copy(OLD, tmp_path / "old.db")
    return f"sqlite:///{tmp_path / 'old.db'}"


def test_an_old_database_reads_reports_and_exports(tmp_path):
    url = copy_of_old(tmp_path)
    status = softevo_process("status", "--db", url, cwd=ROOT)
    assert status.returncode == 0, status.stderr
    assert "finished" in status.stdout and "3/3" in status.stdout
    done = softevo_process("report", "latest", "--db", url, "--out", str(tmp_path / "report"),
                           "--no-animation", "--quiet", cwd=ROOT)
    assert done.returncode == 0, done.stderr
    assert "land-water" in (tmp_path / "report" / "report.md").read_text()
    done = softevo_process("export", "latest", "--db", url, "--out", str(tmp_path / "export"), cwd=ROOT)
    assert done.returncode == 0, done.stderr
    rows = (tmp_path / "export" / "individuals.csv").read_text().splitlines()
    assert len(rows) > 12 and "shape_entropy" in rows[0]


def test_an_old_run_state_resumes_where_it_stopped(tmp_path):
    """The stored state (the flat config of before) reads into today's config and the run
    goes on for two more generations in water."""
    url = copy_of_old(tmp_path)
    engine = create_engine(url)
    with engine.begin() as conn:
        state = conn.execute(select(RunRow.__table__.c.algorithm_state)).scalar_one()
        conn.execute(update(RunRow.__table__).values(generations=5, status="pending"))
    assert "environment" in state["config"] and "evaluation" not in state["config"]  # the old form
    config = Evolution.from_state_dict(state).config
    assert config.evaluation.environment == "land" and config.evaluation.encoding.workspace == (4, 4, 4)
    done = softevo_process("resume", "--db", url, "--workers", "1", "--quiet", cwd=ROOT, timeout=600)
    assert done.returncode == 0, done.stderr
    with engine.connect() as conn:
        generations = conn.execute(select(GenerationRow.__table__.c.generation)).scalars().all()
        status = conn.execute(select(RunRow.__table__.c.status)).scalar_one()
    engine.dispose()
    assert sorted(generations) == [0, 1, 2, 3, 4] and status == "finished"
