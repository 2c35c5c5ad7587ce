"""bench/storage_scale.py on a tiny store (6 x 10, 4 generations evolved, the rest
synthesised): it prints its tables, and the store it builds reads back through the real
queries as a run of that size should (not timed)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from sqlalchemy import func, select

from softevo.service.reports.data import load_experiment
from softevo.service.storage import open_database
from softevo.service.storage.exaptation import exaptation
from softevo.service.storage.models import IndividualRow
from softevo.service.storage.phylogeny import ancestors
from softevo.service.storage.run_tree import run_phylogeny
from softevo.service.storage.runs import list_runs

SCRIPT = Path(__file__).resolve().parents[2] / "bench" / "storage_scale.py"
GENERATIONS, POPULATION = 10, 6


def test_storage_scale_tiny(tmp_path):
    url = f"sqlite:///{tmp_path / 'storage.db'}"
    command = [sys.executable, str(SCRIPT), "--db", url, "--generations", str(GENERATIONS),
               "--population", str(POPULATION), "--evolved", "4", "--repeats", "1"]  # fmt: skip
    out = subprocess.run(command, capture_output=True, text=True, timeout=240, check=True).stdout
    shown = ("individual", "evaluation", "population member", "generation summary", "paper grid: 180 runs",
             "lineage of the final best", "exaptation", "report data load", "genome")  # fmt: skip
    assert all(line in out for line in shown)
    engine = open_database(url, create=False)
    with engine.connect() as conn:
        runs = list_runs(conn, experiment_id=1)
        assert len(runs) == 180 and {r["status"] for r in runs} == {"finished"}
        full = next(r for r in runs if (r["treatment"], r["repetition"]) == ("land-water S3", 0))
        assert full["generation"] == GENERATIONS - 1
        total, nodes = run_phylogeny(conn, full["id"])
        assert total == conn.execute(select(func.count()).select_from(IndividualRow.__table__)).scalar_one()
        assert total >= POPULATION * GENERATIONS - 1
        born = {n["id"]: n["generation_born"] for n in nodes}
        assert all(born[n["parent_id"]] < n["generation_born"] for n in nodes if n["parent_id"] is not None)
        youngest = max(nodes, key=lambda n: n["generation_born"])
        summary = exaptation(conn, full["id"])
        assert summary["founders"] == POPULATION and summary["switch_at"] == GENERATIONS // 2
    lineage = ancestors(engine, youngest["id"])
    assert lineage["parent_id"].isna().iloc[-1] and lineage["generation_born"].is_monotonic_decreasing
    data = load_experiment(engine, 1)
    assert len(data.runs) == 180 and len(data.generations) > 180
