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
    """evolution.treatments' former rule over [(environment, first_generation), ...]."""
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


def test_a_switch_over_spends_its_span_in_compound_worlds():
    schedule = Schedule.parse("land:0,water:4+3")
    assert schedule.spans == (0, 3) and schedule.format() == "land:0,water:4+3"
    assert [schedule.environment_at(g) for g in range(3, 8)] == [
        "land", "land>water@0.250", "land>water@0.500", "land>water@0.750", "water",
    ]  # fmt: skip
    assert [g for g in range(9) if schedule.switches_at(g)] == [4, 5, 6, 7]
    assert schedule != Schedule([("land", 0), ("water", 4)])
    with pytest.raises(ValueError, match="must end before"):
        Schedule([("land", 0), ("water", 4), ("land", 6)], spans=[0, 2, 0])
    with pytest.raises(ValueError, match="nothing to switch over from"):
        Schedule([("land", 0)], spans=[1])


def test_a_treatment_validates_its_switch_over():
    from softevo.errors import UserError
    from softevo.evolution.treatments import Treatment, gradual_grid

    treatment = Treatment("water-land", 0.1, generations=10, switch_at=4, switch_over=3)
    assert treatment.arrival_generation() == 7 and treatment.name.endswith("over 3")
    assert Treatment.from_settings(treatment.to_settings()) == treatment
    with pytest.raises(UserError, match="needs a transition"):
        Treatment("land", 0.1, switch_over=2)
    with pytest.raises(UserError, match="switch-over ends at generation 10"):
        Treatment("land-water", 0.1, generations=10, switch_at=5, switch_over=5)
    grid = gradual_grid("tiny")
    assert [(t.environment, t.switch_over) for t in grid] == [
        ("land-water", 0), ("land-water", 2), ("water-land", 0), ("water-land", 2),
    ]  # fmt: skip
