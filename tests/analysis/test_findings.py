"""The findings table and the per-run summary on hand-made grids (tests/analysis/grid.py)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from softevo.analysis.findings import (
    FINDING_COLUMNS,
    VERDICTS,
    findings_display,
    findings_table,
    headline_findings,
)
from softevo.analysis.rank_tests import holm, jonckheere_terpstra, mann_whitney
from softevo.analysis.run_summary import SUMMARY_COLUMNS, capped, evaluation_seconds, run_summary
from softevo.evolution import environments
from softevo.evolution.stats import vargha_delaney
from tests.analysis.grid import grid_data

LAND, WATER = environments.PAPER
LEVEL = {f"S{k}": k for k in range(1, 6)}


def paper_like(name: str, repetition: int, generation: int) -> tuple[float, float]:
    """Land distance rises and water distance falls with stiffness by the same amount at
    every generation (present in random bodies: the gain is alike at every level); land
    frequency falls and water frequency rises, and evolution widens that (the change from
    generation 0 follows the trend: evolved); every value distinct; transitions end
    between their controls."""
    world, level = name.split(" ")
    k = LEVEL[level]
    noise = 0.37 * repetition + 0.011 * k * repetition
    distance = (k if world == LAND else 6 - k) * 2 + noise + 0.5 * generation
    rank = 6 - k if world == LAND else k  # the frequency's order in the paper
    frequency = rank * 2 + noise + generation * (0.1 * rank + 0.003 * repetition)
    if environments.is_transition(world):
        distance = 3.0 + noise + 0.2 * generation + 0.003 * len(world)
    return distance, frequency


def evolving(name: str, repetition: int, generation: int) -> tuple[float, float]:
    """As ``paper_like``, the distance gain also growing along the paper's order."""
    distance, frequency = paper_like(name, repetition, generation)
    world, level = name.split(" ")
    k = LEVEL[level]
    return distance + 0.3 * generation * (k if world == LAND else 6 - k), frequency


@pytest.fixture(scope="module")
def grid():
    return grid_data(paper_like)


@pytest.fixture(scope="module")
def table(grid):
    return findings_table(grid)


def test_one_row_per_finding_with_the_columns_asked_for(table):
    assert list(table.columns) == FINDING_COLUMNS
    # primary: four trends, two paper contrasts; gain: two trends x (absolute, log);
    # secondary: two frequency levels, two equal-time contrasts
    assert table["family"].tolist() == ["primary"] * 6 + ["gain"] * 4 + ["secondary"] * 4
    assert (
        table["question"].iloc[0].startswith(f"{LAND} distance rises")
        and "(S2, S3, S4, S5)" in table["question"].iloc[0]
    )
    assert "(S1, S2, S3, S4, S5)" in table["question"].iloc[1]
    assert table["measure"].iloc[2].startswith("population's mean actuation frequency, final minus")
    assert table["question"].iloc[10:].str.contains("secondary").all()
    assert table["verdict"].str.split(";").str[0].isin(VERDICTS).all()


def test_verdicts_tell_random_bodies_from_evolution(table):
    verdicts = table["verdict"].str.split(";").str[0]
    # distance: the trend is there at generation 0 and the gain is alike at every level
    assert verdicts.iloc[:2].tolist() == ["present in random bodies"] * 2
    # frequency: the change from generation 0 follows the paper's order
    assert verdicts.iloc[2:4].tolist() == ["evolved"] * 2
    evolved = findings_table(grid_data(evolving), design_figures=False)
    assert evolved["verdict"].str.startswith("evolved").iloc[:2].all()


def test_the_trend_is_the_jt_test_over_the_final_run_values(grid, table):
    row = table.iloc[1]  # water distance falls with stiffness, S1..S5
    final = grid.generations[grid.generations["generation"] == 5]
    groups = [
        final.loc[final["treatment"] == f"{WATER} S{k}", "best_distance"].to_numpy() for k in (5, 4, 3, 2, 1)
    ]
    expected = jonckheere_terpstra(groups)
    assert (row["statistic"], row["p"]) == pytest.approx((expected.statistic, expected.p))
    assert row["n"] == "5+5+5+5+5" and "exact" in row["test"]
    assert row["a12"] == pytest.approx(vargha_delaney(groups[-1], groups[0]))  # S1 over S5
    assert row["a12_low"] <= row["a12"] <= row["a12_high"]
    start = grid.generations[grid.generations["generation"] == 0]
    s1, s5 = (start.loc[start["treatment"] == f"{WATER} S{k}", "best_distance"].to_numpy() for k in (1, 5))
    assert row["a12_generation0"] == pytest.approx(vargha_delaney(s1, s5))
    assert row["adjacent_a12"] == "S4 over S5 1.00; S3 over S4 1.00; S2 over S3 1.00; S1 over S2 1.00"


def test_the_gain_rows_are_per_run_differences(grid, table):
    row = table[table["family"] == "gain"].iloc[0]  # land distance gain, S2..S5
    gens = grid.generations
    groups = []
    for k in (2, 3, 4, 5):
        runs = gens[gens["treatment"] == f"{LAND} S{k}"].set_index(["run_id", "generation"])["best_distance"]
        groups.append((runs.xs(5, level="generation") - runs.xs(0, level="generation")).to_numpy())
    assert row["p"] == pytest.approx(jonckheere_terpstra(groups).p)
    log_row = table[table["family"] == "gain"].iloc[1]
    assert "log gain" in log_row["question"] and log_row["measure"].startswith("log(")


def test_holm_runs_within_each_family(table):
    for family in ("primary", "gain", "secondary"):
        rows = table[table["family"] == family]
        assert rows["p_holm"].to_numpy() == pytest.approx(holm(rows["p"]))
        m = len(rows)
        ranks = rows["p"].rank(method="first").astype(int).to_numpy()
        assert rows["holm_threshold"].to_numpy() == pytest.approx(0.05 / (m - ranks + 1))
    primary = table[table["family"] == "primary"]
    assert (primary["detectable_a12"] > 0.5).all() and primary["runs_needed_a12_071"].notna().all()


def test_the_transition_contrasts(grid, table):
    table = table.set_index("question")
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
    assert paper["a12"] == 0.0 and paper["verdict"].startswith("evolved")  # paper: land->water worse
    wl = [q for q in table.index if q.startswith(f"{WATER}-{LAND}") and "total" in q][0]
    assert table.loc[wl, "verdict"].startswith("reversed")  # the paper: a trend to better


def test_missing_treatments_give_only_the_findings_held():
    no_transitions = grid_data(
        paper_like, keep=lambda name: not environments.is_transition(name.split(" ")[0])
    )
    table = findings_table(no_transitions, design_figures=False)
    primary = table[table["family"] == "primary"]
    assert len(primary) == 4 and primary["p_holm"].to_numpy() == pytest.approx(holm(primary["p"]))
    land_only = grid_data(paper_like, keep=lambda name: name in (f"{LAND} S2", f"{LAND} S5", f"{LAND} S1"))
    table = findings_table(land_only, design_figures=False)
    assert len(table) == 5 and table["question"].str.contains(r"\(S2, S5\)").all()
    assert findings_table(grid_data(paper_like, keep=lambda name: name == f"{WATER} S1")).empty


def test_ties_fall_back_to_the_normal_approximation_and_an_absent_trend_is_not_detected():
    flat = grid_data(
        lambda name, r, g: (float(r % 2), 1.0 + r), keep=lambda name: name.startswith(f"{LAND} ")
    )
    table = findings_table(flat, design_figures=False)
    assert "normal approximation" in table["test"].iloc[0]
    assert table["verdict"].iloc[0].startswith("not detected")


def test_an_opposite_trend_is_reversed():
    reverse = grid_data(lambda name, r, g: (-paper_like(name, r, g)[0], 1.0 + r + 0.01 * LEVEL[name[-2:]]))
    assert findings_table(reverse, design_figures=False)["verdict"].iloc[0].startswith("reversed")


def test_a_trend_that_turns_between_adjacent_levels_says_so():
    def turning(name, r, g):
        distance, frequency = evolving(name, r, g)
        return (distance - 30.0 if name == f"{LAND} S5" else distance), frequency

    row = findings_table(grid_data(turning), design_figures=False).iloc[0]
    assert "turns between S4 and S5" in row["verdict"] and "S5 over S4 0.00" in row["adjacent_a12"]


def test_the_display_puts_each_finding_beside_its_start(grid):
    display = findings_display(headline_findings(grid, design_figures=False))
    first = display.iloc[0]
    assert first["groups"] == " | ".join(f"{LAND} S{k}" for k in (2, 3, 4, 5))
    final = [float(v) for v in first["measure (mean)"].split(" | ")]
    start = [float(v) for v in first["start (mean)"].split(" | ")]
    assert [f - s for f, s in zip(final, start, strict=True)] == pytest.approx([2.5] * 4, abs=0.05)


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
