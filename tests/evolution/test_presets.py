"""The paper presets (``evolution.treatments``) run the paper's algorithm, model and encoding
unless told otherwise, 50 cycles guarded in seconds; the model and the guard travel from the
treatment to every scene; plain treatments and settings stored before keep their meaning."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from softevo.errors import UserError
from softevo.evolution.genotype import random_viable_genotype
from softevo.evolution.treatments import PAPER_CHOICES, PAPER_CYCLES, Treatment, preset_grid
from softevo.worker.tasks import Task, scene_of, scenes_of


def choices(treatment: Treatment) -> tuple[str, str, str, str]:
    return treatment.algorithm, treatment.model, treatment.control_mapping, treatment.body_rule


@pytest.mark.parametrize("preset", ["paper", "gradual"])
def test_presets_run_the_papers_choices_unless_told_otherwise(preset):
    paper = tuple(PAPER_CHOICES[name] for name in ("algorithm", "model", "control_mapping", "body_rule"))
    assert paper == ("pareto", "voxcad-land-water", "evosoro-logistic", "evosoro")
    assert {choices(t) for t in preset_grid(preset, "tiny")} == {paper}
    afpo = {choices(t) for t in preset_grid(preset, "tiny", algorithm="afpo")}
    assert afpo == {("afpo", *paper[1:])}
    plain = {t.model for t in preset_grid(preset, "tiny", model="voxelyze-2", algorithm=None)}
    assert plain == {"voxelyze-2"}


def test_plain_treatments_and_old_settings_keep_their_meaning():
    treatment = Treatment("land", 0.1)
    assert choices(treatment) == ("afpo", "voxelyze-2", "linear", "any")
    stored = {k: v for k, v in treatment.to_settings().items()
              if k not in ("model", "control_mapping", "body_rule")}
    assert Treatment.from_settings(stored) == treatment
    with pytest.raises(UserError, match="unknown model"):
        Treatment("land", 0.1, model="voxelyze-3")
    with pytest.raises(UserError, match="frequency_per_voxel"):
        Treatment("land", 0.1, control_mapping="evosoro", frequency_per_voxel=True)


def test_the_model_reaches_every_scene_and_back_from_storage():
    treatment = preset_grid("paper", "tiny")[5]  # water S1
    config = treatment.evolution_config(3)
    assert config.evaluation.model == "voxcad-land-water" and config.mode == "pareto"
    genome = random_viable_genotype(np.random.default_rng(3), config.encoding)
    task = Task.from_stored(7, genome.to_dict(), treatment.to_settings(), "water", 1e3)
    assert Task.from_json(task.to_json()) == task
    _, scene = scene_of(task)
    assert scene["model"] == "voxcad-land-water" and scene["actuation"]["amplitude"] == 0.14
    old = {k: v for k, v in treatment.to_settings().items() if k != "model"}
    _, old_scene = scene_of(Task.from_stored(7, genome.to_dict(), old, "water", 1e3))
    assert "model" not in old_scene


@pytest.mark.parametrize(("scale", "cycles", "cap"), [("tiny", 2, 1.0), ("pilot", PAPER_CYCLES, 500.0),
                                                     ("study", PAPER_CYCLES, 500.0),
                                                     ("paper", PAPER_CYCLES, 500.0)])
def test_paper_presets_run_50_cycles_guarded_in_seconds(scale, cycles, cap):
    """The fork's sample robots run 50 cycles after InitCmTime; the presets do (the tiny scale,
    CI's, 2), guarded at 50 cycles of 0.1 Hz, the guard reaching every scene (split over a
    compound world's parts) and the cost bound, and settings stored before it read as
    uncapped. Settling is the world's (0.5 s on land, 0 s in water), in the stored settings."""
    grid = preset_grid("paper", scale) + preset_grid("gradual", scale)
    assert {t.max_seconds for t in grid} == {cap} and {t.cycles for t in grid} == {cycles}
    assert {t.control_mapping for t in grid} == {"evosoro-logistic"}
    settings = {t.name: t.to_settings() for t in grid}
    assert settings["water S1"]["settle_seconds"] == {"water": 0.0}
    assert settings["land S1"]["settle_seconds"] == {"land": 0.5}
    assert settings["land-water S3"]["settle_seconds"] == {"land": 0.5, "water": 0.0}
    assert Treatment.from_settings(settings["land-water S3"]) == grid[10]
    treatment = grid[5]  # water S1
    assert treatment.evolution_config(0).evaluation.max_seconds == cap
    genome = random_viable_genotype(np.random.default_rng(4), treatment.evolution_config(0).encoding)
    task = Task.from_stored(7, genome.to_dict(), treatment.to_settings(), "water", 1e3)
    assert Task.from_json(task.to_json()) == task and task.to_json()["max_seconds"] == cap
    _, scene = scene_of(task)
    assert scene["duration"] == {"cycles": treatment.cycles, "max_seconds": cap}
    on_land = dataclasses.replace(task, evaluation=task.evaluation.in_world("land"))
    assert scene["settle_seconds"] == 0.0 and scene_of(on_land)[1]["settle_seconds"] == 0.5
    _, parts = scenes_of(dataclasses.replace(task, evaluation=task.evaluation.in_world("land>water@0.250")))
    assert [p["duration"]["max_seconds"] for p in parts] == pytest.approx([0.75 * cap, 0.25 * cap])
    old = {k: v for k, v in treatment.to_settings().items() if k != "max_seconds"}
    assert Task.from_stored(7, genome.to_dict(), old, "water", 1e3).evaluation.max_seconds is None
    assert Treatment("land", 0.1).max_seconds is None
    for bad in (0, -1.0, float("inf"), "4.5", True):
        with pytest.raises(UserError, match="max_seconds"):
            Treatment("land", 0.1, max_seconds=bad)
