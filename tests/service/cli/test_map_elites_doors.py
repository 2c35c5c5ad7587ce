"""``map-elites`` through its doors: ``softevo run --algorithm map-elites --measures ...
--cells ...`` runs and stores its grid in the treatment's settings, a REST experiment takes
the same fields (``TreatmentIn`` is generated from the declarations), and a wrong grid is one
line: exit status 2 on the command line, 422 over REST."""

from __future__ import annotations

import sqlalchemy as sa
from fastapi.testclient import TestClient

from softevo.evolution.algorithm import Evolution
from softevo.service.api.app import create_app
from softevo.service.api.schemas import TreatmentIn
from softevo.service.settings import Settings
from softevo.service.storage import open_database
from softevo.service.storage.models import RunRow, TreatmentRow
from tests.support import softevo

SMALL = ["--env", "land", "--stiffness", "1", "--population", "3", "--generations", "2",
         "--workspace", "3,3,3", "--cycles", "1", "--quiet", "--workers", "0"]
TOKEN = "map-elites-doors"


def test_softevo_run_takes_the_grid(capsys, tmp_path):
    url = f"sqlite:///{tmp_path / 'me.db'}"
    grid = ["--measures", "frequency,shape_entropy", "--cells", "5,3", "--measure-bounds", "0,5,0,3"]
    code, _, err = softevo(capsys, "run", *SMALL, "--algorithm", "map-elites", *grid, "--db", url)
    assert code == 0, err
    engine = open_database(url)
    with engine.connect() as conn:
        settings = conn.execute(sa.select(TreatmentRow.__table__.c.settings)).scalar_one()
        state = conn.execute(sa.select(RunRow.__table__.c.algorithm_state)).scalar_one()
    engine.dispose()
    assert settings["algorithm"] == "map-elites" and settings["measures"] == ["frequency", "shape_entropy"]
    assert settings["cells"] == [5, 3] and settings["measure_bounds"] == [0, 5, 0, 3]
    grid = Evolution.from_state_dict(state).config.grid
    assert grid.measures == ("frequency", "shape_entropy") and grid.bounds == ((0, 5), (0, 3))


def test_a_wrong_grid_is_one_line_on_the_command_line(capsys, tmp_path):
    url = f"sqlite:///{tmp_path / 'bad.db'}"
    for extra, words in ((["--algorithm", "map-elites", "--cells", "6"], "cells: one count per measure"),
                         (["--algorithm", "map-elites", "--measures", "frequency,height"],
                          "measures: height is no registered trait"),
                         (["--cells", "3,3"], "only an algorithm with an archive takes a grid")):
        code, _, err = softevo(capsys, "run", *SMALL, *extra, "--db", url)
        assert code == 2 and words in err and len(err.strip().splitlines()) == 1, err


def test_rest_takes_the_grid_and_refuses_a_wrong_one(tmp_path):
    body = {"environment": "land", "stiffness_mpa": 1.0, "population": 3, "generations": 2,
            "workspace": [3, 3, 3], "cycles": 1, "algorithm": "map-elites",
            "measures": ["frequency", "branching"], "cells": [6, 6]}
    assert TreatmentIn(**body).cells == [6, 6]
    url = f"sqlite:///{tmp_path / 'rest.db'}"
    open_database(url).dispose()
    settings = Settings(db=url, token=TOKEN, coordinator=False, workers=0, reports=str(tmp_path / "reports"))
    headers = {"Authorization": f"Bearer {TOKEN}"}
    with TestClient(create_app(settings)) as client:
        created = client.post("/experiments", json={"name": "me", "treatments": [body]}, headers=headers)
        assert created.status_code == 201, created.text
        wrong = client.post("/experiments", json={"name": "me", "treatments": [{**body, "cells": [6]}]},
                            headers=headers)
        assert wrong.status_code == 422 and "cells: one count per measure" in wrong.text
        too_many = {"name": "me", "treatments": [{**body, "cells": [2000, 1]}]}
        beyond = client.post("/experiments", json=too_many, headers=headers)
        assert beyond.status_code == 422
