"""The findings table and the per-run summary on hand-made grids (tests/analysis/grid.py)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from softevo.analysis.findings import FINDING_COLUMNS, findings_display, findings_table, headline_findings
from softevo.analysis.rank_tests import holm, jonckheere_terpstra, mann_whitney
from softevo.analysis.run_summary import SUMMARY_COLUMNS, capped, evaluation_seconds, run_summary
from softevo.evolution import environments
from softevo.evolution.stats import vargha_delaney
from tests.analysis.grid import grid_data

LAND, WATER = environments.PAPER
LEVEL = {f"S{k}": k for k in range(1, 6)}


def paper_like(name: str, repetition: int, generation: int) -> tuple[float, float]:
    """Land distance rises and water distance falls with stiffness, land frequency falls and
    water frequency rises, every value distinct; transitions end between their controls."""
    world, level = name.split(" ")
    k = LEVEL[level]
    noise = 0.37 * repetition + 0.011 * k * repetition
    distance = (k if world == LAND else 6 - k) * 2 + noise + 0.5 * generation
    frequency = (6 - k if world == LAND else k) * 2 + noise + 0.001 * generation
    if environments.is_transition(world):
        distance = 3.0 + noise + 0.2 * generation + 0.003 * len(world)
    return distance, frequency


@pytest.fixture(scope="module")
def grid():
    return grid_data(paper_like)


def test_one_row_per_finding_with_the_columns_asked_for(grid):
    table = findings_table(grid)
    assert list(table.columns) == FINDING_COLUMNS
    assert len(table) == 4 + 2 + 2  # four trends, two paper contrasts, two equal-time contrasts
    assert (
        table["question"].iloc[0].startswith(f"{LAND} distance rises")
        and "(S2, S3, S4, S5)" in table["question"].iloc[0]
    )
    assert "(S1, S2, S3, S4, S5)" in table["question"].iloc[1]
    assert table["verdict"].iloc[:4].str.startswith("supported").all()
    assert table["question"].iloc[6:].str.contains("secondary").all()


def test_the_trend_is_the_jt_test_over_the_final_run_values(grid):
    row = findings_table(grid).iloc[1]  # water distance falls with stiffness, S1..S5
    final = grid.generations[grid.generations["generation"] == 5]
    groups = [
        final.loc[final["treatment"] == f"{WATER} S{k}", "best_distance"].to_numpy() for k in (5, 4, 3, 2, 1)
    ]
    expected = jonckheere_terpstra(groups)
    assert (row["statistic"], row["p"]) == pytest.approx((expected.statistic, expected.p))
    assert row["n"] == "5+5+5+5+5" and "exact" in row["test"]
    assert row["a12"] == pytest.approx(vargha_delaney(groups[-1], groups[0]))  # S1 over S5
    start = grid.generations[grid.generations["generation"] == 0]
    s1, s5 = (start.loc[start["treatment"] == f"{WATER} S{k}", "best_distance"].to_numpy() for k in (1, 5))
    assert row["a12_generation0"] == pytest.approx(vargha_delaney(s1, s5))


def test_holm_runs_over_the_headline_findings_and_apart_over_the_secondary(grid):
    table = findings_table(grid)
    assert table["p_holm"].iloc[:6].to_numpy() == pytest.approx(holm(table["p"].iloc[:6]))
    assert table["p_holm"].iloc[6:].to_numpy() == pytest.approx(holm(table["p"].iloc[6:]))
    assert (table["detectable_a12"].iloc[:6] > 0.5).all()


def test_the_transition_contrasts(grid):
    table = findings_table(grid).set_index("question")
    lw = f"{LAND}-{WATER} S3"
    paper = table.loc[[q for q in table.index if q.startswith(lw) and "total" in q][0]]
    equal = table.loc[[q for q in table.index if q.startswith(lw) and "equal time" in q][0]]
    summary = grid.generations
    transition = summary[(summary["treatment"] == lw) & (summary["generation"] == 5)]["best_distance"]
    for row, control_generation in ((paper, 5), (equal, 5 - 3)):
        control = summary[
            (summary["treatment"] == f"{WATER} S3") & (summary["generation"] == control_generation)
        ]
        expected = mann_whitney(transition, control["best_distance"])
        assert row["p"] == pytest.approx(expected.p) and row["statistic"] == expected.statistic
        assert row["a12"] == pytest.approx(vargha_delaney(transition, control["best_distance"]))
    assert paper["a12"] == 0.0 and paper["verdict"].startswith("supported")  # paper: land->water worse
    wl = [q for q in table.index if q.startswith(f"{WATER}-{LAND}") and "total" in q][0]
    assert table.loc[wl, "verdict"].startswith("opposite direction")  # the paper: a trend to better


def test_missing_treatments_give_only_the_findings_held():
    no_transitions = grid_data(paper_like, keep=lambda name: not environments.is_transition(name.split(" ")[0]))
    table = findings_table(no_transitions)
    assert len(table) == 4 and table["p_holm"].to_numpy() == pytest.approx(holm(table["p"]))
    land_only = grid_data(paper_like, keep=lambda name: name in (f"{LAND} S2", f"{LAND} S5", f"{LAND} S1"))
    table = findings_table(land_only)
    assert len(table) == 2 and table["question"].str.contains(r"\(S2, S5\)").all()
    assert findings_table(grid_data(paper_like, keep=lambda name: name == f"{WATER} S1")).empty


def test_ties_fall_back_to_the_normal_approximation_and_an_absent_trend_is_not_detected():
    flat = grid_data(
        lambda name, r, g: (float(r % 2), 1.0 + r), keep=lambda name: name.startswith(f"{LAND} ")
    )
    table = findings_table(flat)
    assert "normal approximation" in table["test"].iloc[0]
    assert table["verdict"].iloc[0] == "not detected"


def test_an_opposite_trend_is_called_so():
    reverse = grid_data(lambda name, r, g: (-paper_like(name, r, g)[0], 1.0 + r + 0.01 * LEVEL[name[-2:]]))
    assert findings_table(reverse)["verdict"].iloc[0] == "opposite direction"


def test_the_display_puts_each_finding_beside_its_start_and_gain(grid):
    display = findings_display(headline_findings(grid))
    first = display.iloc[0]
    assert first["groups"] == " | ".join(f"{LAND} S{k}" for k in (2, 3, 4, 5))
    assert first["gain"] == " | ".join(["2.5"] * 4)  # 0.5 per generation over 5 generations


def test_run_summary_has_one_row_per_run(grid):
    summary = run_summary(grid)
    assert list(summary.columns) == SUMMARY_COLUMNS and len(summary) == len(grid.runs)
    row = summary.iloc[0]
    assert row["best_distance_final"] - row["best_distance_generation0"] == pytest.approx(row["gain"])
    transition = summary[summary["treatment"] == f"{LAND}-{WATER} S3"].iloc[0]
    assert math.isnan(transition["gain"])  # generation 0 on land, the end in water: not compared
    assert transition["start_final_world"] == 3 and (
        transition["world_generation0"],
        transition["world_final"],
    ) == (
        LAND,
        WATER,
    )
    # the tiny preset's 2 cycles at the best robot's frequency, capped at its seconds
    cycles, cap = grid.treatments.set_index("name").loc[row["treatment"], ["cycles", "max_seconds"]]
    seconds = (
        min(cycles / row["best_frequency"], cap)
        if cap == cap and cap is not None
        else cycles / row["best_frequency"]
    )
    assert row["seconds"] == pytest.approx(seconds)
    assert row["distance_per_second"] == pytest.approx(row["best_distance_final"] / seconds)
    assert row["distance_per_cycle"] == pytest.approx(
        row["best_distance_final"] / (seconds * row["best_frequency"])
    )


def test_evaluation_seconds_and_the_cap():
    assert evaluation_seconds([2.0, 0.0, -4.0], 50, None) == pytest.approx([25.0, np.nan, 12.5], nan_ok=True)
    assert evaluation_seconds([2.0, 20.0], 50, 10.0) == pytest.approx([10.0, 2.5])
    assert capped([2.0, 20.0], 50, 10.0).tolist() == [True, False]
    assert capped([2.0], 50, None).tolist() == [False]
    assert capped([2.0], 50, pd.NA).tolist() == [False]
