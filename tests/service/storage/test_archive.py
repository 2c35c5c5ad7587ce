"""Acceptance of the archive views on a real tiny land -> water run: ``softevo archive --json``
and ``GET /runs/{id}/archive`` give the same JSON; each elite is the farthest evaluation of its
world whose measures fall in its cell, one per cell, checked independently from the rows
``softevo export`` writes (the cell rule written out again here with numpy, not
``evolution.archive``) and by docs/sql.md's archive query; the history ends at the archive; a
bad run, generation or world is one clean line (exit 2) on the command line and a 404 over
REST."""

from __future__ import annotations

import json

import httpx
import numpy as np
import pandas as pd
import pytest
from sqlalchemy import text

from softevo.evolution.archive import EPSILON
from tests.service import tinyrun
from tests.service.storage.test_sql_cookbook import cookbook
from tests.support import softevo, softevo_ok


@pytest.fixture(scope="module")
def served(tmp_path_factory):
    """The tiny land -> water run (switch at 3) in SQLite, ``softevo serve`` on it, and its
    ``softevo export`` individuals (one row per evaluation)."""
    folder = tmp_path_factory.mktemp("archive")
    with tinyrun.served(folder, tinyrun.TINY) as (engine, url, run_id, base):
        yield url, run_id, base, folder, engine


def exported(capsys, url: str, run_id: int, folder) -> pd.DataFrame:
    softevo_ok(capsys, "export", f"r{run_id}", "--out", str(folder / "export"), "--db", url)
    return pd.read_csv(folder / "export" / "individuals.csv")


def expected_elites(rows: pd.DataFrame, archive: dict, world: str, generation: int) -> dict:
    """{cell: (individual, distance)}: per cell the farthest evaluation in ``world`` up to
    ``generation``, the first evaluated (generation, then id) among equals."""
    rows = rows[(rows["environment"] == world) & (rows["generation"] <= generation)].copy()
    rows = rows.dropna(subset=["distance", *archive["measures"]])
    indices = []
    axes = zip(archive["measures"], archive["bounds"], archive["cells"], strict=True)
    for name, (low, high), count in axes:
        position = ((count * (rows[name].to_numpy() - low) + EPSILON) / (high - low)).astype(int)
        indices.append(np.clip(position, 0, count - 1))
    rows["cell"] = list(zip(*indices, strict=True))
    rows = rows.sort_values(["distance", "generation", "individual_id"], ascending=[False, True, True])
    best = rows.groupby("cell", sort=False).head(1)
    return {tuple(int(i) for i in cell): (int(ind), float(d))
            for cell, ind, d in zip(best["cell"], best["individual_id"], best["distance"], strict=True)}


@pytest.mark.parametrize("where", [(), ("2", "land"), ("4", "land"), ("3", "water")])
def test_cli_and_rest_agree_and_each_elite_is_its_cells_farthest(served, capsys, where):
    url, run_id, base, folder, engine = served
    args, params = (), {}
    if where:
        args = ("--generation", where[0], "--environment", where[1])
        params = {"generation": where[0], "environment": where[1]}
    cli = json.loads(softevo_ok(capsys, "archive", f"r{run_id}", "--json", "--db", url, *args))
    rest = httpx.get(f"{base}/runs/{run_id}/archive", params=params).json()
    assert cli == rest
    assert cli["measures"] == ["frequency", "branching"] and cli["cells"] == [6, 6]
    assert cli["environments"] == ["land", "water"]
    world, generation = (cli["environment"], cli["generation"])
    assert (world, generation) == ((where[1], int(where[0])) if where else ("water", 4))
    cells = [tuple(elite["cell"]) for elite in cli["elites"]]
    assert len(cells) == len(set(cells)) == cli["filled"] >= 1  # one elite per cell
    expected = expected_elites(exported(capsys, url, run_id, folder), cli, world, generation)
    assert {tuple(e["cell"]): (e["individual"], e["distance"]) for e in cli["elites"]} == expected
    (low_x, high_x), (low_y, high_y) = cli["bounds"]
    grid = {"low_x": low_x, "high_x": high_x, "cells_x": 6, "low_y": low_y, "high_y": high_y, "cells_y": 6}
    with engine.connect() as conn:  # docs/sql.md's archive query: the same elites
        rows = conn.execute(text(cookbook()["archive"]), {"run_id": run_id, "environment": world,
                                                          "generation": generation, **grid}).all()
    assert {(row.cell_x, row.cell_y): (row.individual_id, row.distance) for row in rows} == expected
    assert cli["coverage"] == pytest.approx(len(expected) / 36)
    assert cli["qd_score"] == pytest.approx(sum(d for _, d in expected.values()))
    history = cli["history"]
    assert [h["generation"] for h in history] == list(range(generation + 1))
    assert history[-1] == {key: cli[key] for key in ("generation", "coverage", "qd_score", "filled")}
    assert all(a["filled"] <= b["filled"] and a["qd_score"] <= b["qd_score"] + 1e-12
               for a, b in zip(history, history[1:], strict=False))  # an archive never loses a cell


def test_text_shows_the_grid(served, capsys):
    url, run_id, _, _, _ = served
    args = ("archive", f"r{run_id}", "--db", url, "--environment", "land")
    text = softevo_ok(capsys, *args)
    summary = json.loads(softevo_ok(capsys, *args, "--json"))
    assert f"run {run_id}, land, after generation 4" in text
    assert f"({summary['filled']} of 36 cells)" in text
    grid = [line for line in text.splitlines() if " |" in line]
    empty = sum(line.split("|")[1].split().count(".") for line in grid)
    assert len(grid) == 6 and empty == 36 - summary["filled"]


@pytest.mark.parametrize(
    ("args", "query", "message"),
    [
        (("r999",), "/runs/999/archive", "no run"),
        (("r{run}", "--generation", "9"), "/runs/{run}/archive?generation=9", "generations 0..4, not 9"),
        (("r{run}", "--environment", "moon"), "/runs/{run}/archive?environment=moon", "not 'moon'"),
    ],
)
def test_bad_input_is_one_line(served, capsys, args, query, message):
    url, run_id, base, _, _ = served
    code, out, err = softevo(capsys, "archive", *(a.format(run=run_id) for a in args), "--db", url)
    assert code == 2 and out == "" and message in err and err.count("error:") == 1 and "Traceback" not in err
    response = httpx.get(base + query.format(run=run_id))
    assert response.status_code == 404 and message in response.json()["detail"]


def test_the_grid_is_the_stored_settings_or_the_defaults():
    from softevo.errors import UserError
    from softevo.evolution import traits
    from softevo.service.storage.archive import grid_from_settings

    plain = tinyrun.TINY.to_settings()  # an afpo run: the map-elites options' defaults
    for settings in (plain, {k: v for k, v in plain.items() if k not in ("measures", "cells")}):
        grid = grid_from_settings(settings)
        assert grid.measures == ("frequency", "branching") and grid.cells == (6, 6)
        assert grid.bounds == (traits.get("frequency").bounds, traits.get("branching").bounds)
    stored = grid_from_settings({**plain, "algorithm": "map-elites",
                                 "measures": ["symmetry", "voxel_count", "frequency"], "cells": [2, 3, 4],
                                 "measure_bounds": [0, 1, 0, 64, 1, 5]})
    assert stored.measures == ("symmetry", "voxel_count", "frequency") and stored.cells == (2, 3, 4)
    assert stored.bounds == ((0, 1), (0, 64), (1, 5))
    with pytest.raises(UserError, match="low < high"):
        grid_from_settings({**plain, "algorithm": "map-elites", "measure_bounds": [5, 0, 0, 1]})
