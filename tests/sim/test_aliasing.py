"""The engine never simulates an actuation it cannot resolve: a robot with fewer than
``MIN_RESOLVED_STEPS_PER_CYCLE`` steps per cycle is refused unrun (the unbounded evosoro
mapping reached 11,804 Hz, under one step per cycle of the fork's step), whatever the model."""

from __future__ import annotations

import pytest

from softevo import sim
from softevo.sim.system import MIN_RESOLVED_STEPS_PER_CYCLE, build_robot, steps_per_cycle


def scene(frequency: float, model: str = "voxcad-land-water") -> dict:
    return {"body": [[[2, 2]], [[2, 1]]], "material": {"youngs_modulus": 1e7},
            "actuation": {"frequency": frequency}, "duration": {"cycles": 2},
            "environment": {"kind": "water"}, "model": model}


def test_an_aliased_robot_is_refused_unrun_and_a_resolved_one_runs():
    dt = sim.scene_dt(sim.parse_scene(scene(4.0)))
    limit = 1.0 / (MIN_RESOLVED_STEPS_PER_CYCLE * dt)  # the fastest frequency resolved
    fast = sim.simulate(scene(1.5 * limit))
    assert not fast.stable and fast.steps == 0 and fast.reason.startswith("actuation too fast")
    assert f"fewer than {MIN_RESOLVED_STEPS_PER_CYCLE}" in fast.reason
    slow = sim.simulate(scene(0.5 * limit))
    assert slow.stable and slow.steps > 0


@pytest.mark.parametrize("frequency", [4.0, 1000.0, 11804.0])
def test_steps_per_cycle_is_the_period_over_the_step(frequency):
    parsed = sim.parse_scene(scene(frequency))
    robot = build_robot(parsed)
    assert steps_per_cycle(robot) == pytest.approx(1.0 / (frequency * sim.scene_dt(parsed)))


def test_a_model_with_a_floor_on_steps_per_cycle_is_never_refused():
    """voxelyze-2 shortens its step to 2000 steps a cycle: the same fast robot runs."""
    result = sim.simulate({**scene(200.0, "voxelyze-2"), "duration": {"cycles": 1}})
    assert result.steps > 0 and (result.reason or "").find("too fast") < 0
