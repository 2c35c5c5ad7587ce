"""``softevo power``: repetitions the paper's comparisons need, on the real tiny experiment,
on hand-built pilots whose answer is known (tests/analysis/matched.py), and against
simulated studies with known effects (analysis.calibration)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from softevo.analysis.calibration import power_calibration
from softevo.analysis.power import (
    detectable_a12,
    exact_floor,
    first_feasible_n,
    needed_repetitions,
    pilot_shift,
    rank_test_power,
)
from softevo.evolution.treatments import STUDY_REPETITIONS, Treatment, paper_grid
from softevo.service.storage import open_database
from tests.analysis import matched
from tests.support import softevo

LAND = (
    Treatment("land", 1.0, name="land S4", population=2, generations=4),
    Treatment("land", 0.001, name="land S1", population=2, generations=4),
    Treatment("land", 10.0, name="land S5", population=2, generations=4),
)


def separated(treatment: str, repetition: int, generation: int) -> float:
    """land S4 at 100..103, land S5 at 50..53, land S1 at 1..4, at every generation
    (distance, voxel count and frequency alike)."""
    return {"land S4": 100.0, "land S5": 50.0}.get(treatment, 1.0) + repetition


def alike(treatment: str, repetition: int, generation: int) -> float:
    return 1.0 + repetition


def _pilot(tmp_path, values=separated, repetitions=4):
    url = f"sqlite:///{tmp_path / 'pilot.db'}"
    engine = open_database(url)
    experiment_id = matched.build(engine, LAND, repetitions, values, name="pilot")
    engine.dispose()
    return url, experiment_id


def test_power_on_the_tiny_experiment(capsys, tiny):
    args = ("power", f"e{tiny.experiment_id}", "--db", tiny.url, "--max-n", "20", "--quiet")
    code, out, err = softevo(capsys, *args)
    assert code == 0, err
    lines = out.splitlines()
    assert lines[0].startswith(f"pilot e{tiny.experiment_id}") and "lower end of its 80% interval" in lines[0]
    assert any(
        line.startswith(
            "water->land vs land only, S3 [water-land S3 vs its final world, 1 tests, alpha 0.05]"
        )
        for line in lines
    )
    assert "design at alpha 0.05: n, exact-p floor, smallest A12 detectable at power 0.8" in lines
    assert "  n=3: floor 0.1, detectable A12 none (floor)" in lines
    assert "land fitness, S4 vs S1: not in this experiment" in lines
    code, first, err = softevo(capsys, *args, "--json")
    assert code == 0, err
    payload = json.loads(first)
    (estimate,) = payload["comparisons"]
    assert (estimate["a"], estimate["b"], estimate["generation"]) == ("water-land S3", "land S3", 2)
    assert (estimate["pilot_runs_a"], estimate["pilot_runs_b"]) == (3, 3)
    assert estimate["repetitions"] is None or 2 <= estimate["repetitions"] <= 20
    n = STUDY_REPETITIONS  # the study preset's, the default
    assert estimate["pilot_seeds"] == "0..2" and estimate["study_n"] == n
    assert estimate["detectable_a12"] == pytest.approx(detectable_a12(n, n, 0.05))
    assert [d["n"] for d in payload["designs"]][:3] == [3, 4, 5]
    assert softevo(capsys, *args, "--json")[1] == first  # seeded: the same estimate again


def test_a_clear_difference_needs_the_hand_computed_runs(capsys, tmp_path):
    # fully separated pilots: the exact two-sided Mann-Whitney p of a complete separation is
    # 2 / C(2n, n): 0.1 for n = 3, 0.029 for n = 4, 0.0079 for n = 5
    url, experiment_id = _pilot(tmp_path)
    code, out, err = softevo(capsys, "power", f"e{experiment_id}", "--db", url, "--json", "-q")
    assert code == 0, err
    payload = json.loads(out)
    fitness, frequency = payload["comparisons"]
    assert (fitness["comparison"], fitness["a"], fitness["b"]) == (
        "land fitness, S4 vs S1",
        "land S4",
        "land S1",
    )
    assert (frequency["comparison"], frequency["metric"]) == (
        "frequency vs stiffness on land, S1 vs S5",
        "frequency",
    )
    assert "water fitness, S1 vs S5" in payload["not_in_experiment"]
    for estimate in (fitness, frequency):
        # three stiffness pairs among S1, S4, S5: alpha 0.05 / 3 = 0.0167 -> n = 5
        assert estimate["family"] == "stiffness in land" and estimate["family_size"] == 3
        assert estimate["alpha_bonferroni"] == pytest.approx(0.05 / 3) and estimate["floor_n"] == 5
        assert estimate["repetitions"] == 5 and estimate["power"] == 1.0
        assert estimate["generations"] == 2  # separated from generation 1 on (checked from 1)
        assert estimate["generation"] == 3 and estimate["pilot_generations"] == 4
    assert fitness["pilot_a12"] == 1.0 and frequency["pilot_a12"] == 0.0
    # one comparison per family: alpha 0.05 -> n = 4
    # ten comparisons per family: alpha 0.005 needs 2 / C(2n, n) < 0.005: 2/252 = 0.0079 at
    # n = 5, 2/924 = 0.0022 at n = 6
    code, out, err = softevo(
        capsys, "power", f"e{experiment_id}", "--db", url, "--json", "-q", "--family", "10"
    )
    assert json.loads(out)["comparisons"][0]["repetitions"] == 6


def test_no_difference_never_reaches_the_power(capsys, tmp_path):
    url, experiment_id = _pilot(tmp_path, alike)
    code, out, err = softevo(capsys, "power", f"e{experiment_id}", "--db", url, "--max-n", "12", "-q")
    assert code == 0, err
    line = next(x for x in out.splitlines() if x.startswith("land fitness, S4 vs S1"))
    assert "more than 12 repetitions per treatment" in line
    assert "more than the pilot's 4 generations" in line
    # a "no difference" comes with the smallest effect the design could detect
    assert "no effect the pilot can vouch for" in line
    n = STUDY_REPETITIONS
    assert f"a study of {n} per treatment: power 0.0" in line
    assert f"detects A12 >= {detectable_a12(n, n, 0.05 / 3):.2f}" in line


def test_rank_test_power_and_the_bisection_by_hand():
    # the exact two-sided floor: 2 / C(2n, n) for Mann-Whitney, 2 / 2^n for signed-rank
    assert exact_floor(3) == pytest.approx(0.1) and exact_floor(7) == pytest.approx(2 / 3432)
    assert exact_floor(7, paired=True) == pytest.approx(2 / 128)
    assert first_feasible_n(0.005) == 6 and first_feasible_n(0.005, paired=True) == 9
    assert rank_test_power(30.0, 3, 3, 0.05, resamples=200) == 0.0  # below the floor: never
    assert rank_test_power(30.0, 4, 4, 0.05, resamples=200) == 1.0
    assert rank_test_power(0.0, 7, 7, 0.05, resamples=4000) < 0.06  # the level, no effect
    assert np.isnan(detectable_a12(7, 7, 0.005, paired=True))  # 2/128 > 0.005: nothing detectable
    calls = []

    def power_at(n):
        calls.append(n)
        return 1.0 if n >= 7 else 0.0

    assert needed_repetitions(power_at, 0.8, 50) == (7, 1.0)
    assert len(calls) <= 8
    assert needed_repetitions(lambda n: 0.5, 0.8, 50) == (None, 0.5)


def test_the_pilot_effect_bound_is_below_the_estimate_and_zero_without_evidence():
    d, low = pilot_shift(np.array([1.0, 2.0, 3.0]), np.array([5.5, 6.5, 7.5]))
    assert d == pytest.approx(-4.5) and 0 < low < 4.5
    assert pilot_shift(np.array([1.0, 2.0, 3.0]), np.array([1.5, 2.5, 3.5]))[1] == 0.0


MARGIN = 0.05  # the estimate may exceed the true power by at most this, on average


@pytest.mark.parametrize("a12", [0.71, 0.86, 0.96])
def test_the_estimate_does_not_flatter_on_simulated_studies(a12):
    # pilots of 3 + 3 runs from normal run values with a known effect, a study of 7 per
    # treatment in a family of 10 (alpha 0.005): the true power by simulated studies
    result = power_calibration(a12, pilot_n=3, study_n=7, alpha=0.005, pilots=150)
    assert result["mean estimate"] <= result["true power"] + MARGIN, result
    assert result["pilots above the true power"] <= 0.10 + 0.05, result  # 80% bound: 10% in theory


def test_the_study_never_reuses_pilot_seeds_and_treatments_have_their_own():
    def seeds(scale):
        grid = paper_grid(scale)
        return [{t.seed_of(r) for r in range(t.repetitions)} for t in grid]

    pilot, study = seeds("pilot"), seeds("study")
    assert not set().union(*pilot) & set().union(*study)
    for grid in (pilot, study):
        assert len(set().union(*grid)) == sum(len(s) for s in grid)  # no two treatments share one


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("--alpha", "2"), "--alpha must be between 0 and 1 (got 2.0)"),
        (("--power", "0"), "--power must be between 0 and 1 (got 0.0)"),
        (("--max-n", "1"), "--max-n must be within 2..1000 (got 1)"),
    ],
)
def test_bad_settings_are_one_line_and_exit_2(capsys, tiny, args, message):
    code, _, err = softevo(capsys, "power", f"e{tiny.experiment_id}", "--db", tiny.url, *args)
    assert code == 2 and err == f"error: {message}\n"


def test_a_pilot_without_the_papers_comparisons_or_runs_is_a_user_error(capsys, tmp_path):
    url = f"sqlite:///{tmp_path / 'matched.db'}"
    engine = open_database(url)
    none_id = matched.build(engine)  # land S1, land S3, land-water S3: none of the paper's pairs
    one_id = matched.build(engine, LAND, 1, separated, name="one run")
    engine.dispose()
    code, _, err = softevo(capsys, "power", f"e{none_id}", "--db", url, "-q")
    assert code == 2 and err.count("\n") == 1 and "holds none of the paper's comparisons" in err
    code, _, err = softevo(capsys, "power", f"e{one_id}", "--db", url, "-q")
    assert code == 2 and err.count("\n") == 1
    assert "treatment 'land S4' has 1 run(s) with best_distance at generation 3" in err
    code, _, err = softevo(capsys, "power", "e999", "--db", url, "-q")
    assert code == 2 and "no experiment 'e999'" in err
