"""evolution.schedule: both old conventions reproduced, the text form, bad input."""

from __future__ import annotations

import types

import pytest

from softevo.evolution.schedule import Schedule


def _old_runner_environment_at(schedule, generation):
    """evolution.runner's former rule over [(environment, until_generation), ...]."""
    for environment, until in schedule:
        if generation < until:
            return environment
    return schedule[-1][0]


def _old_treatment_environment_at(schedule, generation):
    """service.treatments' former rule over [(environment, first_generation), ...]."""
    current = schedule[0][0]
    for environment, start in schedule:
        if generation >= start:
            current = environment
    return current


@pytest.mark.parametrize(
    "until", [[("land", 2), ("water", 10)], [("water", 5)], [("land", 1), ("water", 3), ("land", 4)]]
)
def test_the_runners_until_convention_is_reproduced(until):
    schedule = Schedule.from_until(until)
    for generation in range(15):
        assert schedule.environment_at(generation) == _old_runner_environment_at(until, generation)


@pytest.mark.parametrize("first", [[("land", 0)], [("land", 0), ("water", 50)], [("water", 0), ("land", 3)]])
def test_the_treatments_first_convention_is_reproduced(first):
    schedule = Schedule(first)
    assert schedule == first and list(schedule) == first
    for generation in range(60):
        assert schedule.environment_at(generation) == _old_treatment_environment_at(first, generation)


def test_static_and_switches():
    assert Schedule.static("land") == [("land", 0)]
    assert not any(Schedule.static("land").switches_at(g) for g in range(10))
    schedule = Schedule([("land", 0), ("water", 3)])
    assert [g for g in range(10) if schedule.switches_at(g)] == [3]
    assert schedule.environments == ["land", "water"]


def test_switch_moves_an_algorithm_into_the_new_world_once():
    moved = []
    algorithm = types.SimpleNamespace(environment="land")

    def reevaluate_all(environment):
        moved.append(environment)
        algorithm.environment = environment

    algorithm.reevaluate_all = reevaluate_all
    schedule = Schedule([("land", 0), ("water", 3)])
    assert [schedule.switch(algorithm, g) for g in range(6)] == [False, False, False, True, False, False]
    assert moved == ["water"]


@pytest.mark.parametrize("text", ["land:0", "land:0,water:50", "water:0,land:2,water:7"])
def test_text_round_trip(text):
    schedule = Schedule.parse(text)
    assert schedule.format() == text == str(schedule)
    assert Schedule.parse(schedule.format()) == schedule


def test_text_tolerates_spaces():
    assert Schedule.parse(" land:0 , water:5 ") == [("land", 0), ("water", 5)]


@pytest.mark.parametrize(
    "text, problem",
    [
        ("", "empty"),
        ("land", "not environment:first_generation"),
        (":3", "not environment:first_generation"),
        ("land:x", "not an integer"),
        ("land:2", "must start at generation 0"),
        ("land:0,water:0", "not after land at 0"),
        ("land:0,water:-1", ">= 0"),
        ("land:0,,water:4", "not environment:first_generation"),
    ],
)
def test_bad_text_is_a_value_error_naming_the_problem(text, problem):
    with pytest.raises(ValueError, match=problem):
        Schedule.parse(text)


def test_bad_entries_are_value_errors():
    with pytest.raises(ValueError, match="no environment"):
        Schedule([])
    with pytest.raises(ValueError, match="bad environment name"):
        Schedule([("", 0)])
    with pytest.raises(ValueError, match="not \\(environment, first generation\\)"):
        Schedule(["land"])
