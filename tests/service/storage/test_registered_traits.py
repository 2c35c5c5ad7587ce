"""Acceptance (issue 57): a trait registered once (``evolution.traits.register``) is stored
with every evaluation, followed by the exaptation analysis along each line, and shown by the
phylogeny queries, ``softevo phylogeny`` and ``softevo exaptation`` and the REST endpoints of
individuals, lineages, phylogenies and exaptation, with nothing else written for it."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import httpx
import pytest
from sqlalchemy import Engine, select

from softevo.evolution import traits
from softevo.evolution.treatments import Treatment
from softevo.service.storage import phylogeny
from softevo.service.storage.exaptation import exaptation
from softevo.service.storage.models import EvaluationRow
from tests.service import tinyrun
from tests.support import softevo_ok

ROOT = Path(__file__).resolve().parents[3]
PLUGIN = {"SOFTEVO_PLUGINS": "tests.service.plugin_height", "PYTHONPATH": str(ROOT)}
WATER_LAND = Treatment(
    "water-land", 0.1, population=4, generations=5, workspace=(4, 4, 4), cycles=2, switch_at=2, seed=3
)


def height(phenotype) -> float:
    """The plugin's trait (``tests.service.plugin_height``), written again here: importing the
    plugin would register it for the rest of the session."""
    return float(phenotype.body.any(axis=(0, 1)).sum())


@pytest.fixture(scope="module")
def height_trait():
    """``height`` registered in this process for the module's tests."""
    trait = traits.register(traits.Trait("height", "height (voxels)", height, header="high"))
    yield trait
    traits.unregister("height")


def stored_heights(engine: Engine, run_id: int) -> dict[int, float | None]:
    """{individual id: its height at birth}, read from the ``descriptors`` JSON in Python."""
    ev = EvaluationRow.__table__
    with engine.connect() as conn:
        rows = conn.execute(
            select(ev.c.individual_id, ev.c.descriptors)
            .where(ev.c.run_id == run_id)
            .order_by(ev.c.generation.desc())
        ).all()
    return {int(i): (d or {}).get("height") for i, d in rows}  # the first evaluation is written last


def check_lines(summary: dict, born: dict[int, float | None]) -> None:
    """Every surviving line reports ``height`` at its founder, switch and end as stored."""
    assert summary["lines"], "the tiny run keeps no line: nothing to check"
    for line in summary["lines"]:
        followed = line["traits"]["height"]
        assert followed["founder"] == born[line["founder_id"]] is not None
        assert followed["end"] == born[line["individual_id"]] is not None
        assert followed["switch"] == (None if line["switch_id"] is None else born[line["switch_id"]])
    for founder in summary["founder_lines"]:
        assert founder["traits"]["height"] == born[founder["founder_id"]]


def test_a_registered_trait_is_stored_and_followed_along_lines(height_trait, engine):
    """On SQLite and PostgreSQL: stored as measured, read back by the phylogeny queries and
    followed by the exaptation analysis, its first change where the lineage shows it."""
    run_id = tinyrun.new_run(engine, WATER_LAND)
    tinyrun.run_to_end(engine, run_id)
    born = stored_heights(engine, run_id)
    assert born and all(value is not None and 1 <= value <= 4 for value in born.values())
    with engine.connect() as conn:
        summary = exaptation(conn, run_id)
    check_lines(summary, born)

    for line in summary["lines"]:
        lineage = phylogeny.ancestors(engine, line["individual_id"])
        assert [born[int(i)] for i in lineage["id"]] == list(lineage["height"])
        forward = lineage.iloc[::-1]  # the root newcomer first
        after = forward[forward["generation_born"] > forward.loc[forward["id"] == line["founder_id"],
                                                                  "generation_born"].iloc[0]]
        changed = after[after["height"] != born[line["founder_id"]]]
        expected = None if changed.empty else int(changed["generation_born"].iloc[0])
        assert line["traits"]["height"]["first_changed"] == expected
        changes = phylogeny.trait_changes(engine, line["individual_id"], "height")
        assert all(row.value != row.previous for row in changes.itertuples())


@pytest.fixture(scope="module")
def served(height_trait, tmp_path_factory):
    """A finished tiny water->land run in SQLite and ``softevo serve`` on it with the plugin
    that registers ``height``."""
    with tinyrun.served(tmp_path_factory.mktemp("registered"), WATER_LAND, **PLUGIN) as served_run:
        yield served_run


cli = softevo_ok


def test_a_registered_trait_reaches_the_command_line(served, capsys, monkeypatch):
    engine, url, run_id, _ = served
    born = stored_heights(engine, run_id)
    rows = list(csv.DictReader(io.StringIO(cli(capsys, "phylogeny", f"r{run_id}", "--csv", "--db", url))))
    assert "height" in rows[0] and "shape_entropy" in rows[0]
    assert {int(r["id"]): float(r["height"]) for r in rows} == born
    nodes = json.loads(cli(capsys, "phylogeny", f"r{run_id}", "--json", "--db", url))
    assert {n["id"]: n["height"] for n in nodes} == born
    monkeypatch.setenv("COLUMNS", "80")
    table = cli(capsys, "phylogeny", f"r{run_id}", "--db", url)
    assert max(len(row) for row in table.splitlines()) <= 80
    lines = table.splitlines()
    head = " ".join(lines[2 : next(k for k, line in enumerate(lines) if line.startswith("\u2521"))])
    assert {"distance", "active", "voxels", "high"} <= set(head.replace("\u2503", " ").split())

    summary = json.loads(cli(capsys, "exaptation", f"r{run_id}", "--json", "--db", url))
    check_lines(summary, born)
    text = cli(capsys, "exaptation", f"r{run_id}", "--db", url)
    rows = [row.replace("\u2502", " ").split() for row in text.splitlines()]
    assert sum("high" in row for row in rows) == len(summary["lines"])  # a row per line


def test_a_registered_trait_reaches_rest(served):
    engine, _, run_id, base = served
    born = stored_heights(engine, run_id)
    summary = httpx.get(f"{base}/runs/{run_id}/exaptation", timeout=30).json()
    check_lines(summary, born)
    page = httpx.get(f"{base}/runs/{run_id}/phylogeny", params={"limit": 1000}, timeout=30).json()
    assert {n["id"]: n["height"] for n in page["individuals"]} == born
    final = summary["lines"][0]["individual_id"]
    lineage = httpx.get(f"{base}/individuals/{final}/lineage", timeout=30).json()
    assert [entry["height"] for entry in lineage] == [born[entry["id"]] for entry in lineage]
    assert all(isinstance(entry["voxel_count"], int) for entry in lineage)  # built-in fields kept
    individual = httpx.get(f"{base}/individuals/{final}", timeout=30).json()
    assert individual["evaluations"][0]["traits"]["height"] == born[final]
    schema = httpx.get(f"{base}/openapi.json", timeout=30).json()["components"]["schemas"]
    assert schema["LineTraits"]["additionalProperties"] == {"$ref": "#/components/schemas/TraitAlongLine"}
    assert set(schema["LineTraits"]["required"]) == set(traits.along_lines()) - {"height"}
