"""Acceptance: on a tiny water->land run made here, ``softevo exaptation`` lists founders
whose lines reach the last generation, every final individual's ancestry reaches a root
newcomer, and the same numbers come from the docs/sql.md cookbook queries and from
``GET /runs/{id}/exaptation`` (paged) over real HTTP; ``softevo phylogeny`` and
``GET /runs/{id}/phylogeny`` list the same tree."""

from __future__ import annotations

import csv
import io
import json

import httpx
import pytest
from sqlalchemy import select, text

from softevo.evolution.treatments import Treatment
from softevo.service.cli import main
from softevo.service.storage.models import IndividualRow, PopulationMemberRow
from tests.service import tinyrun
from tests.service.storage.test_sql_cookbook import cookbook
from tests.support import softevo_ok

WATER_LAND = Treatment(
    "water-land", 0.1, population=4, generations=5, workspace=(4, 4, 4), cycles=2, switch_at=2, seed=3
)


@pytest.fixture(scope="module")
def served(tmp_path_factory):
    """A finished tiny water->land run in SQLite and ``softevo serve`` on it."""
    with tinyrun.served(tmp_path_factory.mktemp("exaptation"), WATER_LAND) as served_run:
        yield served_run


cli = softevo_ok


def test_exaptation_agrees_across_cli_sql_and_rest(served, capsys):
    engine, url, run_id, base = served
    summary = json.loads(cli(capsys, "exaptation", f"r{run_id}", "--json", "--db", url))
    ind, pm = IndividualRow.__table__, PopulationMemberRow.__table__
    with engine.connect() as conn:
        final = set(
            conn.execute(
                select(pm.c.individual_id).where(pm.c.run_id == run_id, pm.c.generation == 4)
            ).scalars()
        )
        founders = set(
            conn.execute(
                select(pm.c.individual_id).where(pm.c.run_id == run_id, pm.c.generation == 1)
            ).scalars()
        )
        newcomers = set(
            conn.execute(select(ind.c.id).where(ind.c.run_id == run_id, ind.c.parent_id.is_(None))).scalars()
        )
        sql = cookbook()

        def query(name, **params):
            return [tuple(r) for r in conn.execute(text(sql[name]), params)]

        switch = query("switch", run_id=run_id)[0][0]
        surviving = query("surviving", run_id=run_id)
        dominant = query("dominant_founders", run_id=run_id, switch_at=switch)

    # founders whose lines reach the last generation, and every ancestry reaches a newcomer
    assert summary["switch_at"] == switch == 2 and summary["generation"] == 4
    assert summary["environments"] == ["water", "land"] and summary["founders"] == len(founders) == 4
    assert summary["founders_surviving"] >= 1 and summary["lines"]
    assert {line["individual_id"] for line in summary["lines"]} <= final
    assert {line["founder_id"] for line in summary["lines"]} <= founders
    assert summary["every_line_rooted"] and set(summary["roots"]) <= newcomers
    assert {final_id for final_id, _, _ in surviving} == final
    assert {root for _, root, _ in surviving} == set(summary["roots"]) <= newcomers
    assert {line["root_id"] for line in summary["lines"]} <= set(summary["roots"])

    # the cookbook SQL gives the same founders and line counts
    by_founder = {
        f["founder_id"]: (f["lines"], f["front_lines"]) for f in summary["founder_lines"] if f["lines"]
    }
    assert {f: (n, front) for f, n, front in dominant} == by_founder
    assert summary["founders_surviving"] == len(dominant)
    assert summary["lines_total"] == sum(n for _, n, _ in dominant)

    # and so does the REST endpoint, page by page
    pages, offset = [], 0
    while True:
        page = httpx.get(f"{base}/runs/{run_id}/exaptation", params={"limit": 2, "offset": offset}).json()
        pages.extend(page["lines"])
        offset += 2
        if offset >= page["lines_total"]:
            break
    assert {k: v for k, v in page.items() if k not in ("lines", "limit", "offset")} == {
        k: v for k, v in summary.items() if k != "lines"
    }
    assert pages == summary["lines"]
    with engine.connect() as conn:
        born = dict(conn.execute(select(ind.c.id, ind.c.generation_born).where(ind.c.run_id == run_id)).all())
    for line in summary["lines"]:
        for trait in line["traits"].values():
            changed = trait["first_changed"]
            assert changed is None or born[line["founder_id"]] < changed <= born[line["individual_id"]]

    text_out = cli(capsys, "exaptation", str(run_id), "--db", url)
    assert f"with lines to the end: {summary['founders_surviving']}" in text_out


def test_the_exaptation_tables_fit_80_columns(served, capsys, monkeypatch):
    """Every line of the text output within 80 columns, and every trait of every surviving
    line on one row, its three values whole."""
    from softevo.service.cli.phylogeny import line_headers

    def cell(value) -> str:  # as the table writes a value
        return "-" if value is None else f"{value:.3g}" if isinstance(value, float) else str(value)

    engine, url, run_id, base = served
    summary = json.loads(cli(capsys, "exaptation", str(run_id), "--json", "--db", url))
    monkeypatch.setenv("COLUMNS", "80")
    text_out = cli(capsys, "exaptation", str(run_id), "--db", url)
    assert max(len(row) for row in text_out.splitlines()) <= 80
    rows = [row.replace("\u2502", " ").split() for row in text_out.splitlines()]
    assert summary["lines"], "the tiny run keeps no line: nothing to check"
    for line in summary["lines"]:
        for trait, header in line_headers().items():
            t = line["traits"][trait]
            cells = [header, cell(t["founder"]), cell(t["switch"]), cell(t["end"])]
            assert any(row[-5:-1] == cells or row[-6:-2] == cells for row in rows), (header, text_out)


def test_phylogeny_cli_and_rest_list_the_same_tree(served, capsys):
    engine, url, run_id, base = served
    rows = list(csv.DictReader(io.StringIO(cli(capsys, "phylogeny", f"r{run_id}", "--csv", "--db", url))))
    with engine.connect() as conn:
        count = conn.execute(
            select(IndividualRow.__table__.c.id).where(IndividualRow.__table__.c.run_id == run_id)
        ).all()
    assert len(rows) == len(count)
    first = httpx.get(f"{base}/runs/{run_id}/phylogeny", params={"limit": 5}).json()
    second = httpx.get(f"{base}/runs/{run_id}/phylogeny", params={"limit": 5, "offset": 5}).json()
    assert first["total"] == len(rows)
    served_ids = [n["id"] for n in first["individuals"] + second["individuals"]]
    assert served_ids == [int(r["id"]) for r in rows[:10]]
    born_in_water = {int(r["id"]) for r in rows if r["environment"] == "water"}
    assert born_in_water and all(int(r["generation_born"]) < 2 for r in rows if int(r["id"]) in born_in_water)
    as_of = json.loads(cli(capsys, "phylogeny", f"r{run_id}", "--generation", "1", "--json", "--db", url))
    assert as_of and all(r["generation_born"] <= 1 for r in as_of)
    assert all(r["last_generation"] is None or r["last_generation"] <= 1 for r in as_of)


def test_user_mistakes_are_one_line(served, capsys):
    engine, url, run_id, base = served
    with pytest.raises(SystemExit) as exit_info:
        main(["exaptation", "e99", "--db", url])  # e1 is an experiment of one run: its run
    assert exit_info.value.code == 2
    assert "no run or experiment 'e99'" in capsys.readouterr().err
    assert httpx.get(f"{base}/runs/999/exaptation").status_code == 404
    static = tinyrun.new_run(
        engine, Treatment("land", 1.0, population=2, generations=1, workspace=(3, 3, 3), cycles=1)
    )
    response = httpx.get(f"{base}/runs/{static}/exaptation")
    assert response.status_code == 404 and "no environment transition" in response.json()["detail"]


def test_the_report_has_an_exaptation_section(served, tmp_path):
    from softevo.analysis.exaptation import exaptation_figure, run_statistics
    from softevo.analysis.report import Document, to_markdown
    from softevo.analysis.report import exaptation_block as block
    from softevo.service.reports.data import load_experiment
    from softevo.service.reports.report import exaptation_data
    from softevo.service.storage.exaptation import exaptation

    engine, url, run_id, _ = served
    data = load_experiment(engine, 1)
    stats = run_statistics(data, exaptation_data(engine, data))
    with engine.connect() as conn:
        summary = exaptation(conn, run_id)
    (row,) = stats.to_dict(orient="records")
    assert (row["run_id"], row["founders"], row["founders_surviving"]) == (
        run_id, summary["founders"], summary["founders_surviving"],
    )  # fmt: skip
    survivors = [f["traits"]["voxel_count"] for f in summary["founder_lines"] if f["lines"]]
    everyone = [f["traits"]["voxel_count"] for f in summary["founder_lines"]]
    assert row["voxel_count_shift"] == pytest.approx(
        sum(survivors) / len(survivors) - sum(everyone) / len(everyone)
    )
    figure = exaptation_figure(data, exaptation_data(engine, data), stats, tmp_path)
    assert figure.png.is_file() and figure.size_px[0] > 1000
    doc = Document("report")
    block(doc, stats)
    markdown = to_markdown(doc, tmp_path)
    assert "## Exaptation across the switch" in markdown and str(summary["founders_surviving"]) in markdown


def test_the_founders_lines_say_why_they_can_sum_past_the_population(served, capsys):
    """A final member counts under each founder among its ancestors: the table says so,
    with the sum and the final population it is compared with (issue 49.15)."""
    engine, url, run_id, base = served
    summary = json.loads(cli(capsys, "exaptation", f"r{run_id}", "--json", "--db", url))
    total = sum(f["lines"] for f in summary["founder_lines"])
    out = " ".join(cli(capsys, "exaptation", f"r{run_id}", "--db", url).split())
    assert f"lines to the end: {total} over {summary['final_population']} final members" in out
    assert "counts once under each founder among its ancestors" in out
