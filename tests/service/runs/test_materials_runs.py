"""Treatments with per-voxel materials and frequencies: ``softevo run --evolve-stiffness
--frequency-per-voxel`` stores individuals whose re-simulated scene carries the fields and
reproduces the stored distance; old settings without the options still read."""

from __future__ import annotations

import numpy as np
import pytest
from sqlalchemy import select

from softevo import sim
from softevo.evolution.evaluation import encoding_from_settings as encoding_of
from softevo.evolution.treatments import Treatment
from softevo.service.storage import open_database
from softevo.service.storage.models import EvaluationRow, IndividualRow, RunRow, TreatmentRow
from softevo.worker.tasks import Task, scene_of
from tests.service.cli.test_cli_runs import TINY, softevo


@pytest.mark.parametrize(("flags", "fields"), [
    (["--evolve-stiffness"], {"youngs_modulus_field"}),
    (["--frequency-per-voxel"], {"frequency_field"}),
    (["--evolve-stiffness", "--frequency-per-voxel"], {"youngs_modulus_field", "frequency_field"}),
])
def test_run_with_fields_stores_reproducible_individuals(capsys, tmp_path, flags, fields):
    db = f"sqlite:///{tmp_path / 'fields.db'}"
    code, out, err = softevo(capsys, "run", "--env", "water", "--stiffness", "0.1", *flags,
                             *TINY, "--db", db)
    assert code == 0, err
    engine = open_database(db)
    ind, ev, runs, tr = (IndividualRow.__table__, EvaluationRow.__table__, RunRow.__table__,
                         TreatmentRow.__table__)
    with engine.connect() as conn:
        rows = conn.execute(
            select(ind.c.id, ind.c.genome, tr.c.settings, ev.c.environment, ev.c.distance,
                   ev.c.stable)
            .join(ev, ev.c.individual_id == ind.c.id)
            .join(runs, ind.c.run_id == runs.c.id)
            .join(tr, runs.c.treatment_id == tr.c.id)
            .where(ev.c.error.is_(None))
        ).all()
    assert rows
    settings = rows[0].settings
    assert settings["evolve_stiffness"] == ("--evolve-stiffness" in flags)
    assert settings["frequency_per_voxel"] == ("--frequency-per-voxel" in flags)
    scenes, stored = [], []
    for row in rows:
        if len(scenes) == 6:
            break
        task = Task.from_stored(row.id, row.genome, row.settings, row.environment,
                                Treatment.from_settings(row.settings).stiffness_pa)
        _, scene = scene_of(task)
        if 2 not in np.asarray(scene["body"]):  # a passive body is not simulated: it travels 0
            continue
        assert fields <= set(scene)
        assert not ({"youngs_modulus_field", "frequency_field"} - fields) & set(scene)
        scenes.append(scene)
        stored.append(row.distance)
    assert scenes
    results = sim.simulate_many(scenes)
    for result, distance in zip(results, stored, strict=True):
        assert result.distance == distance  # the same scene, the same engine: exactly


def test_evolved_stiffness_uses_the_paper_range_by_default():
    treatment = Treatment("land", 0.1, evolve_stiffness=True)
    assert treatment.stiffness_range_mpa == (0.001, 10.0)
    encoding = encoding_of(treatment.to_settings())
    assert encoding.evolve_stiffness and encoding.stiffness_range == (1e3, 1e7)


def test_old_settings_without_the_options_read_as_off():
    settings = Treatment("water", 1.0).to_settings()
    for key in ("evolve_stiffness", "frequency_per_voxel", "stiffness_range_mpa"):
        settings.pop(key)
    treatment = Treatment.from_settings(settings)
    assert not treatment.evolve_stiffness and not treatment.frequency_per_voxel
    encoding = encoding_of(settings)
    assert not encoding.evolve_stiffness and not encoding.frequency_per_voxel


def test_bad_options_are_one_line(capsys, tmp_path):
    db = f"sqlite:///{tmp_path / 'x.db'}"
    code, _, err = softevo(capsys, "run", "--env", "land", "--db", db)
    assert code == 2 and "--stiffness" in err
    code, _, err = softevo(capsys, "run", "--env", "land", "--evolve-stiffness",
                           "--stiffness-range", "5,1", "--db", db)
    assert code == 2 and "stiffness range" in err


def test_rest_treatment_takes_the_options():
    from softevo.service.api.requests import request_treatments
    from softevo.service.api.schemas import ExperimentIn

    body = ExperimentIn.model_validate({"name": "m", "treatments": [
        {"environment": "land", "stiffness_mpa": 0.1, "evolve_stiffness": True,
         "frequency_per_voxel": True, "stiffness_range_mpa": [0.01, 1.0]},
        {"environment": "water", "stiffness_mpa": 0.1}]})
    evolved, plain = request_treatments(body)
    assert evolved.evolve_stiffness and evolved.frequency_per_voxel
    assert evolved.stiffness_range_mpa == (0.01, 1.0)
    assert encoding_of(evolved.to_settings()).stiffness_range == (1e4, 1e6)
    assert not plain.evolve_stiffness and not plain.frequency_per_voxel
