"""``service.plan.spec``: a spec file read without the API's request models gives the
treatments the API gives for the same body, and every problem in one line naming the field."""

from __future__ import annotations

import pytest

from softevo.errors import UserError
from softevo.service.api.requests import request_treatments
from softevo.service.api.schemas import ExperimentIn, PresetIn
from softevo.service.plan.spec import spec_treatments

LISTED = {"name": "x", "treatments": [
    {"environment": "land-water", "stiffness_mpa": 0.1, "switch_at": 2, "population": 4, "generations": 3},
    {"environment": "water", "stiffness_mpa": 1.0, "name": "wet", "evolve_stiffness": True},
]}  # fmt: skip
PRESET = {"preset": "gradual", "scale": "tiny", "repetitions": 2, "seed": 7, "algorithm": "pareto"}


def test_a_spec_reads_as_the_api_reads_its_body():
    assert spec_treatments(LISTED) == request_treatments(ExperimentIn.model_validate(LISTED))
    assert spec_treatments(PRESET) == request_treatments(PresetIn.model_validate(PRESET))
    names = [t.name for t in spec_treatments(LISTED)]
    assert names[1] == "wet" and names[0]  # a treatment without a name has its default one


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ([], "f.json: not an experiment spec"),
        ({"name": "x"}, "f.json: treatments: must be a list of 1..200 treatments"),
        ({"name": "x", "treatments": [], "extra": 1}, "f.json: unknown field(s) extra"),
        ({"name": "x", "treatments": ["land"]}, "f.json: treatments.0: must be an object"),
        ({"name": "x", "treatments": [{"environment": "land", "stiffness_mpa": 1, "population": 20_000}]},
         "f.json: treatments.0: population must be within 2..10,000"),
        ({"name": "x", "treatments": [{"environment": "land", "stiffness_mpa": 1, "workspace": ["a", 1, 1]}]},
         "f.json: treatments.0: workspace must be 3 integers"),
        ({"name": "", "treatments": [{"environment": "land", "stiffness_mpa": 1}]}, "f.json: name: required"),
        ({"preset": "paper", "seed": -1}, "f.json: seed: must be an integer >= 0"),
        ({"preset": "paper", "scale": "huge"}, "f.json: unknown scale 'huge'"),
        ({"preset": "paper", "cores": 2}, "f.json: unknown field(s) cores"),
    ],
)  # fmt: skip
def test_a_wrong_spec_is_one_line_naming_the_field(spec, message):
    with pytest.raises(UserError) as caught:
        spec_treatments(spec, where="f.json")
    assert str(caught.value).startswith(message) and "\n" not in str(caught.value), str(caught.value)
