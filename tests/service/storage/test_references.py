"""One resolver for every command that takes a run or an individual (``service.storage.runs``):
``latest``, ``r5``, ``e2`` and names work in ``phylogeny``, ``exaptation``, ``lineage``,
``show``, ``export-vxa`` and ``best``; ``softevo best RUN`` and ``GET /runs/{id}/best`` give
the best individual per world."""

from __future__ import annotations

import json

import httpx
import pandas as pd
import pytest

from softevo.evolution.treatments import Treatment
from softevo.service.runs.submit import create
from softevo.service.storage import open_database
from tests.service.rq_support import Processes, service_env
from tests.support import softevo

TINY = ["--population", "3", "--generations", "4", "--workspace", "3,3,3", "--cycles", "1"]
NAME = "ref-test"


def make_runs(capsys, db: str, *extra: str) -> None:
    code, _, err = softevo(
        capsys, "run", "--env", "water-land", "--stiffness", "0.1", "--switch-at", "2", *TINY,
        "--workers", "0", "--quiet", "--db", db, *extra,
    )  # fmt: skip
    assert code == 0, err


def best_from_export(capsys, tmp_path, db: str) -> dict[str, float]:
    code, out, err = softevo(capsys, "export", "latest", "--out", str(tmp_path / "out"), "--db", db)
    assert code == 0, err
    evaluations = pd.read_csv(tmp_path / "out" / "individuals.csv")
    return evaluations.groupby("environment")["distance"].max().to_dict()


def test_every_command_takes_latest_and_names(capsys, tmp_path):
    db = f"sqlite:///{tmp_path / 'refs.db'}"
    make_runs(capsys, db)
    best = best_from_export(capsys, tmp_path, db)

    code, out, err = softevo(capsys, "best", "latest", "--json", "--db", db)
    assert code == 0, err
    rows = json.loads(out)
    assert [r["environment"] for r in rows] == ["water", "land"]  # first met first
    assert {r["environment"]: r["distance"] for r in rows} == pytest.approx(best)
    land_best = rows[-1]["individual_id"]

    experiment = pd.read_csv(tmp_path / "out" / "runs.csv")["experiment"].tolist()
    assert experiment == ["water-land S=0.1MPa"]  # the treatment's name (was: "run")
    for reference in ("latest", "r1", "1", "run-1", "e1", "water-land S=0.1MPa"):
        code, out, err = softevo(capsys, "phylogeny", reference, "--json", "--db", db)
        assert code == 0, (reference, err)
        assert {row["id"] for row in json.loads(out)} >= {land_best}
    code, out, err = softevo(capsys, "phylogeny", "latest", "--generation", "99", "--db", db)
    assert code == 2 and err.count("\n") == 1, err  # was: the whole tree
    assert "--generation 99 is past run 1's last: it has stored generations 0..3" in err
    code, out, err = softevo(capsys, "exaptation", "latest", "--json", "--db", db)
    assert code == 0 and json.loads(out)["run_id"] == 1, err

    code, out, err = softevo(capsys, "lineage", "latest", "--json", "--db", db)
    assert code == 0, err
    assert json.loads(out)[0]["id"] == land_best  # the run's best in its last world
    code, out, err = softevo(capsys, "lineage", str(land_best), "--json", "--db", db)
    assert code == 0 and json.loads(out)[0]["id"] == land_best

    vxa = tmp_path / "best.vxa"
    code, out, err = softevo(capsys, "export-vxa", "r1", "--out", str(vxa), "--db", db)
    assert code == 0 and vxa.exists(), err
    gif = tmp_path / "best.gif"
    code, out, err = softevo(capsys, "show", "latest", "--out", str(gif), "-q", "--db", db)
    assert code == 0 and gif.exists(), err


def test_a_reference_to_several_runs_or_none_is_one_line(capsys, tmp_path):
    db = f"sqlite:///{tmp_path / 'refs.db'}"
    make_runs(capsys, db, "--name", "mine")
    assert softevo(capsys, "best", "mine", "--db", db)[0] == 0
    engine = open_database(db)
    create(engine, NAME, [Treatment("land", 0.1, population=3, generations=2, repetitions=2)])
    engine.dispose()
    out = {"show": ["--out", str(tmp_path / "x.gif")], "export-vxa": ["--out", str(tmp_path / "x.vxa")]}
    for command in ("best", "phylogeny", "lineage", "exaptation", "show", "export-vxa"):
        for reference in ("latest", NAME):
            code, _, err = softevo(capsys, command, reference, *out.get(command, []), "--db", db)
            assert code == 2 and err.count("\n") == 1, (command, err)
            assert err.startswith(f"error: {reference!r} names 2 runs (r2, r3); give one, e.g. r2"), err
    code, _, err = softevo(capsys, "best", "r99", "--db", db)
    assert code == 2 and err.count("\n") == 1 and "no run or experiment 'r99'" in err
    code, out, err = softevo(capsys, "best", "r2", "--db", db)
    assert code == 0 and "no evaluated individual yet" in out, err


def test_rest_best_per_world(tmp_path, capsys):
    db = f"sqlite:///{tmp_path / 'refs.db'}"
    make_runs(capsys, db)
    code, out, err = softevo(capsys, "best", "r1", "--json", "--db", db)
    assert code == 0, err
    group = Processes(tmp_path, service_env(db, None, SOFTEVO_WORKERS="1"))
    try:
        _, base = group.serve("--no-coordinator")
        answer = httpx.get(f"{base}/runs/1/best")
        assert answer.status_code == 200, answer.text
        assert answer.json() == json.loads(out)
        assert httpx.get(f"{base}/runs/99/best").status_code == 404
    finally:
        group.stop_all()
