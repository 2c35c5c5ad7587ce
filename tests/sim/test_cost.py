"""The cost model and the sleep engine: voxel-steps as the engine counts them, the sleep
engine's results, errors and its workers' results."""

from __future__ import annotations

import numpy as np
import pytest

from softevo import sim
from softevo.evolution.evaluation import EvaluationSpec
from softevo.evolution.genotype import EncodingConfig, random_viable_genotype
from softevo.sim import parse_scene, scene_steps
from softevo.sim.cost import MEASURED, voxel_steps
from softevo.sim.engines import EngineUnavailable
from softevo.sim.system import I_STEPS, build_robot
from softevo.worker.tasks import Task, scenes_of


def random_scenes(config: EncodingConfig, n: int, seed: int) -> list:
    rng = np.random.default_rng(seed)
    scenes = []
    for k in range(n):
        environment = ("land", "water")[k % 2]
        model = ("voxcad-land-water", "voxelyze-2")[(k // 2) % 2]
        spec = EvaluationSpec(environment, 10 ** rng.uniform(3, 7), 2, model=model, max_seconds=1.0,
                              encoding=config)
        task = Task.from_genome(random_viable_genotype(rng, config), spec, id=k)
        scenes.append(parse_scene(scenes_of(task)[1][0]))
    return scenes


@pytest.mark.parametrize("config", [
    EncodingConfig(workspace=(5, 5, 5), control_mapping="evosoro", body_rule="evosoro"),
    EncodingConfig(workspace=(4, 4, 4), frequency_per_voxel=True),
    EncodingConfig(workspace=(4, 4, 4), evolve_stiffness=True),
])
def test_voxel_steps_are_the_engines_own_count(config):
    """The fast count (no robot built for uniform materials) equals the built robot's."""
    for scene in random_scenes(config, 8, seed=3):
        robot = build_robot(scene)
        built = (len(robot.pos), int(robot.iparams[I_STEPS]))
        assert voxel_steps(scene) == built == (len(robot.pos), scene_steps(scene))


def test_the_cost_grows_with_stiffness_and_is_higher_in_water():
    config = EncodingConfig(workspace=(4, 4, 4))
    genome = random_viable_genotype(np.random.default_rng(1), config)
    seconds = {}
    for environment in ("land", "water"):
        for pa in (1e5, 1e7):
            spec = EvaluationSpec(environment, pa, 8, model="voxcad-land-water", encoding=config)
            task = Task.from_genome(genome, spec, id=0)
            seconds[environment, pa] = MEASURED.scene_seconds(parse_scene(scenes_of(task)[1][0]))
    assert seconds["land", 1e7] > seconds["land", 1e5] > 0
    assert seconds["water", 1e5] > seconds["land", 1e5]


def test_the_sleep_engine_answers_a_fixed_distance_per_body():
    config = EncodingConfig(workspace=(4, 4, 4))
    scenes = random_scenes(config, 4, seed=5)
    first = sim.simulate_many(scenes, engine="sleep", device="x1000")
    again = sim.simulate_many(scenes[::-1], engine="sleep", device="x1000")[::-1]
    assert [r.distance for r in first] == [r.distance for r in again]
    assert len({r.distance for r in first}) == 4 and all(0 <= r.distance < 5 for r in first)
    assert all(r.stable and r.steps == voxel_steps(s)[1] for r, s in zip(first, scenes, strict=True))
    for device in ("x0", "fast", "x-1"):
        with pytest.raises(EngineUnavailable, match="speed-up"):
            sim.simulate_many(scenes[:1], engine="sleep", device=device)


def test_sleep_workers_return_results_without_descriptors(monkeypatch):
    from softevo.worker.evaluate import evaluate_batch

    config = EncodingConfig(workspace=(4, 4, 4))
    genome = random_viable_genotype(np.random.default_rng(2), config)
    task = Task.from_genome(genome, EvaluationSpec("water", 1e6, 2, encoding=config), id=7).to_json()
    monkeypatch.setenv("SOFTEVO_ENGINE", "sleep")
    monkeypatch.setenv("SOFTEVO_DEVICE", "x1000")
    (result,) = evaluate_batch([task])
    assert result["id"] == 7 and result["stable"] and result["error"] is None
    assert result["descriptors"] is None and result["voxel_count"] > 0
