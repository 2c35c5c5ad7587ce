"""Reprs of results are a line, not their trajectories (``sim.Result``, ``worker.tasks.TaskResult``)."""

from __future__ import annotations

import numpy as np

from softevo import sim
from softevo.evolution.outcome import Outcome
from softevo.worker.tasks import TaskResult


def test_a_simulation_result_repr_is_short():
    body = np.array([[[2]], [[1]], [[2]]]).tolist()
    result = sim.simulate({"body": body, "duration": {"cycles": 1}, "record": {"every": 5}})
    text = repr(result)  # was: every frame and trajectory sample, thousands of numbers
    assert len(text) < 400 and "\n" not in text, text
    assert f"distance={result.distance:.6g}" in text and "voxels=3" in text
    assert f"com_trajectory=<{len(result.com_trajectory['t'])} samples>" in text
    assert f"frames=<{len(result.frames['t'])}>" in text


def test_a_task_result_repr_leaves_the_phenotype_out():
    body = np.ones((10, 10, 10), int).tolist()
    result = TaskResult(1, Outcome(0.5), voxel_count=1000, phenotype={"body": body})
    assert "phenotype" not in repr(result) and len(repr(result)) < 300
    assert TaskResult.from_json(result.to_json()) == result
