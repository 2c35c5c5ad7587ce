"""``sim.scene_dt`` and ``sim.scene_steps``: the engine's own step and step count, read
without building the robot where the materials are uniform, for every kind of scene (one
material, stiffness and frequency fields, both models, the cycle cap binding or not)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from softevo import sim
from softevo.sim.scene import parse_scene
from softevo.sim.system import F_DT, I_SETTLE_STEPS, I_STEPS, build_robot, step_counts
from tests.sim._support import stable_dt


def random_scene(rng: np.random.Generator, k: int) -> dict:
    """A small random scene; every third with a frequency field, every fifth with a
    stiffness field, the models alternating."""
    body = rng.choice([0, 1, 2], size=(3, 4, 3))
    body[1, 1, 1] = 2
    scene = {
        "body": body.tolist(),
        "material": {"youngs_modulus": float(10 ** rng.uniform(3, 7))},
        "actuation": {"frequency": float(rng.uniform(0.5, 5))},
        "duration": {"cycles": 2},
        "settle_seconds": 0.3,
        "model": ("voxelyze-2", "voxcad-land-water")[k % 2],
    }
    if k % 3 == 0:
        scene["frequency_field"] = rng.uniform(0.5, 5, body.shape).tolist()
    if k % 5 == 0:
        scene["youngs_modulus_field"] = (10 ** rng.uniform(3, 7, body.shape)).tolist()
    return scene


@pytest.mark.parametrize("k", range(30))
def test_scene_dt_and_steps_are_the_built_robots(k):
    scene = parse_scene(random_scene(np.random.default_rng(k), k))
    robot = build_robot(scene)
    assert sim.scene_dt(scene) == robot.fparams[F_DT]  # bit for bit
    assert sim.scene_steps(scene) == robot.iparams[I_STEPS]
    assert step_counts(scene, sim.scene_dt(scene)) == (robot.iparams[I_SETTLE_STEPS], robot.iparams[I_STEPS])


def test_the_step_is_the_stable_step_or_the_cycle_cap():
    """docs/physics.md's step for a stiff robot; a very soft one at 2 Hz is capped at
    1 / (2000 f) by voxelyze-2 and not by the paper's engine."""
    stiff = {
        "body": [[[2, 1]]],
        "material": {"youngs_modulus": 1e6, "density": 1000.0},
        "voxel_size": 0.01,
        "actuation": {"frequency": 2.0},
        "duration": {"cycles": 1},
    }
    assert sim.scene_dt(parse_scene(stiff)) == pytest.approx(stable_dt(0.01, 1000.0, 1e6, 0.5), rel=1e-15)
    soft = {**stiff, "material": {"youngs_modulus": 1.0, "density": 1000.0}}
    assert sim.scene_dt(parse_scene(soft)) == 1.0 / (2.0 * 2000)
    paper = {**soft, "model": "voxcad-land-water"}
    assert sim.scene_dt(parse_scene(paper)) == pytest.approx(stable_dt(0.01, 1000.0, 1.0, 0.7), rel=1e-15)


def test_the_count_is_settling_then_duration_and_a_huge_duration_overflows():
    scene = parse_scene({"body": [[[1, 2]]], "duration": {"seconds": 1.0}, "settle_seconds": 0.25})
    dt = sim.scene_dt(scene)
    assert sim.scene_steps(scene) == round(0.25 / dt) + math.ceil(1.0 / dt - 1e-9)
    with pytest.raises(OverflowError):
        sim.scene_steps(parse_scene({"body": [[[1]]], "duration": {"cycles": 1e300}}))
