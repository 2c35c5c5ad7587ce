"""Each treatment option is declared once (``evolution.options``): an option declared alone
reaches ``softevo run``, the REST schema, the limits, the stored settings and the report's
methods paragraph; ``softevo run`` and REST offer the same options (issue 57)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
import typer

from softevo.analysis.methods import evaluation_methods, methods_text
from softevo.errors import UserError
from softevo.evolution import options
from softevo.evolution.genotype import Phenotype
from softevo.evolution.treatments import Treatment
from softevo.service.api.schemas import TreatmentIn, treatment_model
from softevo.service.cli import runs
from softevo.service.runs.limits import check_treatment
from tests.support import softevo

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
SUBSTEPS = options.Option("substeps", "evaluation", int, 4, least=1, most=1000, limit=64, unit="steps",
                          help="substeps of a test's own option")
RUN_OWN = {"ctx", "name", "db", "workers", "quiet"}  # softevo run's parameters that are no option


@pytest.fixture
def substeps():
    options.declare(SUBSTEPS)
    try:
        yield SUBSTEPS
    finally:
        options.undeclare(SUBSTEPS.name)


def _run_parameters() -> set[str]:
    app = typer.Typer()
    runs.register(app)
    command = typer.main.get_command(app).commands["run"]
    return {param.name for param in command.params} - RUN_OWN


def test_run_and_rest_offer_the_same_options():
    fields = set(TreatmentIn.model_fields) - {"name"}
    assert _run_parameters() == fields == {o.name for o in options.declared()}
    assert "objectives" in fields  # REST had it alone


def test_a_declared_option_is_offered_by_softevo_run(capsys, substeps):
    code, out, _ = softevo(capsys, "run", "--help")
    assert code == 0 and "--substeps" in out and "substeps of a test's own option" in out
    assert "substeps" in _run_parameters()
    code, out, err = softevo(capsys, "run", "--env", "land", "--stiffness", "1", "--substeps", "100",
                             "--db", "sqlite:////proc/never/x.db")
    assert (code, out, err) == (2, "", "error: substeps must be within 1..64 (got 100)\n")  # nothing stored


def test_a_declared_option_is_in_the_rest_schema_and_reaches_the_treatment(substeps):
    model = treatment_model()
    schema = model.model_json_schema()["properties"]["substeps"]
    assert (schema["default"], schema["minimum"], schema["maximum"]) == (4, 1, 64)
    assert "substeps of a test's own option (steps)" == schema["description"]
    body = model.model_validate({"environment": "land", "stiffness_mpa": 1.0, "substeps": 8})
    assert Treatment.from_settings({**body.model_dump(), "name": ""}).substeps == 8
    with pytest.raises(ValueError, match="less than or equal to 64"):
        model.model_validate({"environment": "land", "stiffness_mpa": 1.0, "substeps": 65})


def test_a_declared_option_is_limited_stored_and_reported(substeps):
    treatment = Treatment("land", 1.0, name="t", substeps=100)
    assert treatment.substeps == 100 and treatment.evaluation_part.substeps == 100
    with pytest.raises(UserError, match=r"^substeps must be within 1\.\.64 \(got 100\)$"):
        check_treatment(treatment)
    with pytest.raises(UserError, match=r"^substeps must be an integer within 1\.\.1,000 \(got 0\)$"):
        Treatment("land", 1.0, substeps=0)
    settings = treatment.to_settings()
    assert settings["substeps"] == 100
    assert Treatment.from_settings(json.loads(json.dumps(settings))) == treatment
    assert Treatment.from_settings({k: v for k, v in settings.items() if k != "substeps"}).substeps == 4

    rows = pd.DataFrame([settings, Treatment("land", 1.0, name="u").to_settings()])
    robot = Phenotype(body=np.full((2, 2, 2), 2, np.int8), phase=np.zeros((2, 2, 2)), frequency=2.0)
    text = methods_text(evaluation_methods(rows, pd.DataFrame({"treatment": [], "frequency": []}), robot))
    mine, other = text.split("u: ")
    assert "substeps = 100 steps" in mine and "substeps" not in other


def test_older_settings_and_dispatch_settings_still_load():
    stored = {"environment": "water", "stiffness_mpa": 0.1, "name": "old", "population": 8, "generations": 4,
              "workspace": [5, 5, 5], "cycles": 2, "repetitions": 1, "seed": 0, "genomes_per_task": 4,
              "switch_at": None, "settle_seconds": {"water": 0.0}}
    treatment = Treatment.from_settings(stored)
    assert (treatment.name, treatment.body_rule, treatment.workspace) == ("old", "any", (5, 5, 5))
    assert "genomes_per_task" not in treatment.to_settings()
    with pytest.raises(UserError, match="unknown treatment field"):
        Treatment.from_settings({**stored, "colour": "red"})


def test_copies_keep_the_parts():
    import dataclasses

    treatment = Treatment("land-water", 0.1, population=8, objectives=("distance",))
    for copy in (treatment.replace(seed=7), dataclasses.replace(treatment, seed=7)):
        assert copy.seed == 7 and copy.population == 8 and copy.name == treatment.name
        assert copy.objectives == ("distance",) and copy.schedule() == treatment.schedule()
    assert treatment.replace(seed=0) == treatment


def test_a_plugin_option_is_in_the_api_schema():
    """The option of a deployment's plugin (``SOFTEVO_PLUGINS``) reaches the served
    OpenAPI schema: ``TreatmentIn`` is made from the declarations when the app is built."""
    script = ("import json; from softevo.plugins import load_plugins; load_plugins(); "
              "from softevo.service.api.app import create_app; "
              "print(json.dumps(create_app().openapi()['components']['schemas']['TreatmentIn']))")
    env = {**os.environ, "SOFTEVO_PLUGINS": "tests.service.plugin_option", "PYTHONPATH": ROOT}
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, cwd=ROOT,
                          timeout=300)
    assert done.returncode == 0, done.stderr
    field = json.loads(done.stdout)["properties"]["drag_scale"]  # not imported here: it declares
    assert (field["maximum"], field["minimum"], field["default"]) == (10.0, 0.1, 1.0)
