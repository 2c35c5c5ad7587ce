"""One way from a stored individual to its task (``analysis.robots.stored_task``): the task of
an evaluation, with that evaluation's world and stiffness; the REST route, the report and
``softevo show`` build the same one, and each says in its own way when there is none."""

from __future__ import annotations

import types

import pandas as pd
import pytest
from fastapi import HTTPException

from softevo.analysis.robots import stored_task
from softevo.errors import UserError
from softevo.service.api import stored as route
from softevo.service.reports.report import stored_robots
from softevo.service.storage.individuals import individual_record


def _record(tiny_record: dict, rows: list[tuple[str, float]]) -> dict:
    """A stored record whose evaluations are ``rows`` of (environment, stiffness)."""
    evaluations = pd.DataFrame(
        [
            {"generation": g, "environment": env, "stiffness": pa, "distance": 0.1 * g}
            for g, (env, pa) in enumerate(rows)
        ],
        columns=["generation", "environment", "stiffness", "distance"],
    )
    return {**tiny_record, "evaluations": evaluations}


@pytest.fixture(scope="module")
def best_record(tiny, tiny_data):
    final = tiny_data.final_populations()
    return individual_record(tiny.engine, int(final.loc[final["distance"].idxmax(), "individual_id"]))


def test_the_task_is_the_evaluations_own_world_and_stiffness(best_record):
    """A run whose stiffness changed replays each evaluation at the stiffness it ran with."""
    record = _record(best_record, [("water", 1e5), ("land", 2e5), ("land", 3e5), ("water", 4e5)])
    latest = stored_task(record)
    assert (latest.environment, latest.evaluation.youngs_modulus) == ("water", 4e5)
    on_land = stored_task(record, "land")
    assert (on_land.environment, on_land.evaluation.youngs_modulus) == ("land", 3e5)
    settings = best_record["treatment"].to_settings()
    assert (on_land.id, on_land.genome, on_land.evaluation.cycles) == (
        best_record["id"],
        best_record["genome"],
        settings["cycles"],
    )


def test_without_such_an_evaluation_it_is_a_user_error(best_record):
    with pytest.raises(UserError, match=r"individual \d+ was never evaluated$"):
        stored_task(_record(best_record, []))
    with pytest.raises(UserError, match="was never evaluated in water"):
        stored_task(_record(best_record, [("land", 1e5)]), "water")
    with pytest.raises(UserError, match="environment must be land or water"):
        stored_task(_record(best_record, [("land", 1e5)]), "moon")


def test_elsewhere_puts_it_in_a_world_it_never_ran_in(best_record):
    """``softevo show --environment water`` of a land robot: its latest stiffness, in water;
    a world it ran in still replays that evaluation."""
    record = _record(best_record, [("land", 1e5), ("land", 2e5)])
    what_if = stored_task(record, "water", elsewhere=True)
    assert (what_if.environment, what_if.evaluation.youngs_modulus) == ("water", 2e5)
    assert stored_task(record, "land", elsewhere=True) == stored_task(record, "land")
    with pytest.raises(UserError, match="environment must be land or water"):
        stored_task(record, "moon", elsewhere=True)


def test_the_route_and_the_report_build_the_same_task(tiny, tiny_data):
    services = types.SimpleNamespace(engine=tiny.engine)
    report = stored_robots(tiny.engine)
    transition = tiny_data.final_populations().query("treatment == 'water-land S3'")
    individual_id = int(transition["individual_id"].iloc[0])  # evaluated in water, then on land
    for environment in (None, "water", "land"):
        task = route.stored_task_or_404(services, individual_id, environment)
        assert task == report.scene(individual_id, environment)[1]["task"]
        assert task == stored_task(individual_record(tiny.engine, individual_id), environment)
        assert task.environment == (environment or "land")


def test_the_route_answers_404_where_analysis_says_why(tiny, tiny_data):
    services = types.SimpleNamespace(engine=tiny.engine)
    static = tiny_data.final_populations().query("treatment == 'land S3'")
    individual_id = int(static["individual_id"].iloc[0])
    for missing, environment, why in (
        (999_999, None, "no individual 999999"),
        (individual_id, "water", "was never evaluated in water"),
    ):
        with pytest.raises(HTTPException) as caught:
            route.stored_task_or_404(services, missing, environment)
        assert caught.value.status_code == 404 and why in caught.value.detail
