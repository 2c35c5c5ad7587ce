"""A hand-built experiment of four treatments for the experiment page and the downloads
(``tests.analysis.matched`` writes it): land S1 and land S3, water S3, and land-water S3
(switch at generation 3); three repetitions each (seeds 0, 1, 2), population 2, 3 or 5
generations. Its comparisons hold every kind of family: stiffness in land, a transition
against its final world (land-water S3 vs water S3), cross-world pairs (described), and
start vs end. Each generation's distance is ``value``: it differs between the runs of a
treatment, so every interval has a width (and some t intervals reach below 0)."""

from __future__ import annotations

from sqlalchemy import Engine

from softevo.evolution.treatments import Treatment
from softevo.service.storage.experiments import NewTreatment, create_experiment
from tests.analysis import matched

NAME = "compared"
SWITCH_AT = 3  # of land-water S3
IN_WATER = 0.1  # land-water S3 in water goes a tenth of its land distance, as swimmers do
TREATMENTS = (
    Treatment("land", 0.001, name="land S1", population=2, generations=3),
    Treatment("land", 0.1, name="land S3", population=2, generations=5),
    Treatment("water", 0.1, name="water S3", population=2, generations=5),
    Treatment("land-water", 0.1, name="land-water S3", population=2, generations=5, switch_at=SWITCH_AT),
)
REPETITIONS = 3
BASE = {"land S1": 1.0, "land S3": 10.0, "water S3": 0.5, "land-water S3": 2.0}


def value(treatment: str, repetition: int, generation: int) -> float:
    """The distance of every member of that run's population at that generation (after
    land-water S3's switch, a tenth: its best robot ever is a land one, its best in its
    last world a water one)."""
    scale = IN_WATER if treatment == "land-water S3" and generation >= SWITCH_AT else 1.0
    return scale * (BASE[treatment] * (1 + 0.1 * generation) + 0.37 * repetition * (1 + generation))


def build(engine: Engine) -> int:
    """The experiment above (its id), and an experiment "empty" with one treatment and no
    run (nothing to compare yet)."""
    experiment_id = matched.build(engine, TREATMENTS, REPETITIONS, value, name=NAME)
    with engine.begin() as conn:
        create_experiment(conn, "empty", [NewTreatment("land S1", TREATMENTS[0].to_settings(), [])])
    return experiment_id
