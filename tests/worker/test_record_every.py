"""A replay's frame rate and frame budget read the engine's step and step count
(``sim.scene_dt``, ``sim.scene_steps``), not a formula of their own: where the model's cycle
cap shortens the step (a very soft robot), the frames still come at about 60 per second."""

from __future__ import annotations

import math

import numpy as np
import pytest

from softevo import sim
from softevo.evolution.evaluation import EvaluationSpec
from softevo.evolution.genotype import EncodingConfig, random_viable_genotype
from softevo.worker.tasks import DEFAULT_RECORD_FPS, Task, default_record_every, replay, scenes_of
from tests.sim._support import stable_dt

ENCODING = EncodingConfig(workspace=(3, 3, 3))


def _task(youngs_modulus: float) -> Task:
    genome = random_viable_genotype(np.random.default_rng(5), ENCODING)
    return Task.from_genome(genome, EvaluationSpec("land", youngs_modulus, 1, encoding=ENCODING), id=3)


@pytest.mark.parametrize("youngs_modulus", [1e6, 1.0])
def test_default_record_every_is_60_frames_a_second_at_the_engines_step(youngs_modulus):
    _, (scene,) = scenes_of(_task(youngs_modulus))
    dt = sim.scene_dt(sim.parse_scene(dict(scene)))
    assert default_record_every(scene) == max(1, round(1.0 / (DEFAULT_RECORD_FPS * dt)))
    if youngs_modulus == 1.0:  # the cycle cap binds: shorter than docs/physics.md's step
        parsed = sim.parse_scene(dict(scene))
        assert dt < stable_dt(parsed.voxel_size, parsed.material.density, 1.0, parsed.dt_fraction)


def test_a_replay_runs_at_the_step_and_for_the_steps_sim_gives():
    task = _task(1e5)
    _, (scene,) = scenes_of(task)
    parsed = sim.parse_scene(dict(scene))
    frames = replay(task, every=1, max_frames=10)
    dt, steps = sim.scene_dt(parsed), sim.scene_steps(parsed)
    every = math.ceil(steps / 20)  # raised from 1: at most twice the 10 frames kept are recorded
    assert frames["dt"] == dt
    assert frames["t"][-1] == pytest.approx(steps // every * every * dt)
