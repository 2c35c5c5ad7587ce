"""The headline findings: one test per hypothesis of the paper (issue 46), as a table
(``findings.csv``, ``FINDING_COLUMNS``).

The primary measure is each run's best distance in its final generation (one value per
run, as the paper); frequency is each run's mean actuation frequency over its final
population. Treatments are found by world and stiffness (``analysis.power.
treatment_named``), so only the findings the experiment holds are returned.

Headline findings (``TRENDS``, then the transitions' paper contrasts), Holm-corrected
together (``p_holm``):

- the four stiffness trends, each a Jonckheere-Terpstra test, one-sided in the paper's
  direction (``analysis.rank_tests``; exact p without ties), over the runs of the stiffness
  levels present (land S2..S5: the paper calls S1 on land non-functional; water S1..S5), at
  the last generation every run of those treatments has stored. ``statistic`` is J
  counting pairs in the hypothesised order. ``a12`` is the Vargha-Delaney A12 of the
  extreme groups in the hypothesis' direction (the level the hypothesis puts highest over
  the one it puts lowest: land distance S5 over S2, water distance S1 over S5, land
  frequency S2 over S5, water frequency S5 over S1); above 0.5 reads in that direction;
- each transition (a treatment that switches worlds) against the static control of its
  final world at its stiffness, the paper's contrast: the transition's runs at their
  final generation against the control's runs at the same generation (equal total
  generations). Two-sided Mann-Whitney U (exact p without ties): the paper presents its
  transitions as preliminary, with no direction stated beforehand (it found land->water
  worse, p < 0.01, and water->land a non-significant trend to better), so either direction
  counts. ``a12`` = A12 of the transition over the control.

Secondary rows (question ending "(secondary)"), Holm-corrected among themselves: each
transition at equal time in its final world, against the control at generation (the
transition's final generation - its arrival generation), when both have spent as many
generations in that world.

``a12_generation0``: the same A12 on the same runs' values at the start: generation 0 for
the trends (random robots: an effect there was not evolved); for a transition, its arrival
generation (its population's first in the final world) against the control's generation
0. ``detectable_a12``: the smallest A12 (above 0.5) a Mann-Whitney test of the two groups
``a12`` compares detects with 80% power at alpha / (the number of tests Holm corrects
over: its strictest threshold), one-sided for the trends (``analysis.power``'s normal
model); the trend test also uses the middle levels, so this bounds its detectable effect
from above. Empty when no effect can be significant at that n.

``verdict``: "supported" (p_holm < 0.05, in the paper's direction), "opposite direction"
(significant the other way: for a trend, its reverse one-sided test below alpha / m),
"not detected" (or "not detected, no effect detectable at this n"), with "; already at
generation 0" (or "; already at arrival") when the same test on the starting values is
significant at alpha / m in the same direction. No test ever pairs land with water: every
test compares runs measured in one world.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from softevo.analysis.data import ExperimentData
from softevo.analysis.matching import arrival_generation, last_common_generation
from softevo.analysis.power import detectable_a12, treatment_named
from softevo.analysis.rank_tests import RankTest, holm, jonckheere_terpstra, mann_whitney
from softevo.analysis.run_summary import best_distance_at
from softevo.analysis.stats_tables import ALPHA, POWER
from softevo.evolution import environments
from softevo.evolution.stats import vargha_delaney

FINDING_COLUMNS = [
    "question", "measure", "test", "n", "statistic", "p", "p_holm", "a12", "a12_generation0",
    "detectable_a12", "verdict",
]  # fmt: skip
STIFFNESS_LEVELS_MPA = {"S1": 0.001, "S2": 0.01, "S3": 0.1, "S4": 1.0, "S5": 10.0}
MEASURES = {
    "best_distance": "best distance in the final generation, per run (voxel lengths)",
    "frequency": "mean actuation frequency of the final population, per run (Hz)",
}
JT = "Jonckheere-Terpstra, one-sided"
MW = "Mann-Whitney U, two-sided"
SECONDARY = "(secondary)"
_LAND, _WATER = environments.PAPER


@dataclass(frozen=True)
class Trend:
    """A stiffness trend: ``metric`` in ``world`` rises along ``levels`` (stiffness names of
    ``STIFFNESS_LEVELS_MPA``, in the order the hypothesis says the values rise)."""

    question: str
    world: str
    metric: str
    levels: tuple[str, ...]


TRENDS = (
    Trend(f"{_LAND} distance rises with stiffness", _LAND, "best_distance", ("S2", "S3", "S4", "S5")),
    Trend(f"{_WATER} distance falls with stiffness", _WATER, "best_distance", ("S5", "S4", "S3", "S2", "S1")),
    Trend(f"{_LAND} frequency falls with stiffness", _LAND, "frequency", ("S5", "S4", "S3", "S2")),
    Trend(f"{_WATER} frequency rises with stiffness", _WATER, "frequency", ("S1", "S2", "S3", "S4", "S5")),
)


@dataclass
class Finding:
    """One row of the table and the groups behind it: ``labels`` (treatment names),
    ``final`` and ``start`` (their runs' values at the compared and at the starting
    generation), ``generations`` (compared, start) per group."""

    row: dict
    labels: tuple[str, ...] = ()
    final: tuple[np.ndarray, ...] = ()
    start: tuple[np.ndarray, ...] = ()
    generations: tuple[tuple[int | None, int | None], ...] = ()
    one_sided: bool = True
    expected_above: bool = True  # a two-sided contrast: the paper's direction
    start_test: RankTest | None = field(default=None)
    reverse: RankTest | None = field(default=None)


# ---- run values ----------------------------------------------------------------------------
def run_values(data: ExperimentData, name: str, generation: int | None, metric: str) -> np.ndarray:
    """One value per run of treatment ``name`` at ``generation``: its best distance (the
    generation summary) or its population's mean |frequency|; runs without it left out."""
    if generation is None:
        return np.array([])
    run_ids = data.runs.loc[data.runs["treatment"] == name, "run_id"]
    if metric == "best_distance":
        values = best_distance_at(data, generation).reindex(run_ids)
    else:
        members = data.populations_at(generation)
        members = members[members["run_id"].isin(run_ids)]
        values = members["frequency"].abs().groupby(members["run_id"]).mean()
    values = values.to_numpy(float)
    return values[np.isfinite(values)]


def _a12(high: np.ndarray, low: np.ndarray) -> float:
    return vargha_delaney(high, low) if high.size and low.size else math.nan


# ---- the findings ----------------------------------------------------------------------------
def trend_finding(data: ExperimentData, trend: Trend) -> Finding | None:
    """The trend's test over the levels the experiment holds (None with fewer than two)."""
    found = [(level, treatment_named(data.treatments, trend.world, STIFFNESS_LEVELS_MPA[level]))
             for level in trend.levels]  # fmt: skip
    found = [(level, name) for level, name in found if name is not None]
    if len(found) < 2:
        return None
    names = [name for _, name in found]
    generation = last_common_generation(data.runs, names)
    final = tuple(run_values(data, n, generation, trend.metric) for n in names)
    start = tuple(run_values(data, n, 0, trend.metric) for n in names)
    if sum(v.size > 0 for v in final) < 2:
        return None
    test, start_test = jonckheere_terpstra(final), jonckheere_terpstra(start)
    ordered = sorted((level for level, _ in found), key=lambda s: STIFFNESS_LEVELS_MPA[s])
    question = f"{trend.question} ({', '.join(ordered)})"
    row = _row(question, MEASURES[trend.metric], f"{JT} ({test.method})", final, test,
               _a12(final[-1], final[0]), _a12(start[-1], start[0]))  # fmt: skip
    return Finding(row, tuple(names), final, start, tuple((generation, 0) for _ in names),
                   start_test=start_test, reverse=jonckheere_terpstra(final, "decreasing"))  # fmt: skip


def transition_findings(data: ExperimentData) -> list[tuple[Finding, Finding]]:
    """Per transition treatment whose final world has a static control at its stiffness:
    (the paper's contrast, the contrast at equal time in the final world)."""
    found = []
    for _, treatment in data.treatments[data.treatments["switch_at"].notna()].iterrows():
        world = environments.final(treatment["environment"])
        control = treatment_named(data.treatments, world, float(treatment["stiffness_mpa"]))
        end = data.end_generation(treatment["name"])
        if control is None or end is None:
            continue
        arrival = arrival_generation(treatment)
        paper = _contrast(data, treatment, control, (end, arrival), (end, 0), "equal total generations")
        equal = _contrast(data, treatment, control, (end, arrival), (end - arrival, 0),
                          f"equal time in {world} {SECONDARY}")  # fmt: skip
        found.append((paper, equal))
    return found


def _contrast(data, treatment, control: str, at: tuple[int, int], control_at: tuple[int, int], how: str):
    name = treatment["name"]
    final, start = (
        (run_values(data, name, g, "best_distance"), run_values(data, control, c, "best_distance"))
        for g, c in zip(at, control_at, strict=True)
    )
    test, start_test = mann_whitney(*final), mann_whitney(*start)
    question = f"{name} vs {control}, {how}: generation {at[0]} vs {control_at[0]}"
    expected_above = environments.final(treatment["environment"]) == _LAND  # the paper: water->land better
    row = _row(question, MEASURES["best_distance"], f"{MW} ({test.method})", final, test,
               _a12(*final), _a12(*start))  # fmt: skip
    return Finding(row, (name, control), final, start, (at, control_at), one_sided=False,
                   expected_above=expected_above, start_test=start_test)  # fmt: skip


def _row(question, measure, test_name, groups, test: RankTest, a12: float, a12_start: float) -> dict:
    return {"question": question, "measure": measure, "test": test_name,
            "n": "+".join(str(v.size) for v in groups), "statistic": test.statistic, "p": test.p,
            "p_holm": math.nan, "a12": a12, "a12_generation0": a12_start,
            "detectable_a12": math.nan, "verdict": ""}  # fmt: skip


def headline_findings(data: ExperimentData) -> list[Finding]:
    """The findings the experiment holds: headline rows (trends, the transitions' paper
    contrasts) then secondary rows, each family Holm-corrected, with detectable A12 and
    verdict (module doc)."""
    trends = [f for f in (trend_finding(data, t) for t in TRENDS) if f is not None]
    transitions = transition_findings(data)
    headline = trends + [paper for paper, _ in transitions]
    secondary = [equal for _, equal in transitions]
    for family in (headline, secondary):
        _adjust(family)
    return headline + secondary


def _adjust(family: list[Finding]) -> None:
    adjusted = holm([f.row["p"] for f in family])
    m = int(np.isfinite([f.row["p"] for f in family]).sum())
    for finding, p_holm in zip(family, adjusted, strict=True):
        finding.row["p_holm"] = p_holm
        finding.row["detectable_a12"] = _detectable(finding, m)
        finding.row["verdict"] = verdict(finding, m)


def _detectable(finding: Finding, m: int) -> float:
    high, low = finding.final[-1], finding.final[0]
    if m < 1 or min(high.size, low.size) < 2:
        return math.nan
    alpha = ALPHA / m * (2 if finding.one_sided else 1)  # one-sided at alpha = two-sided at 2 alpha
    return detectable_a12(int(high.size), int(low.size), min(alpha, 0.999), POWER, False)


def verdict(finding: Finding, m: int) -> str:
    """The finding's verdict (module doc) in a family of ``m`` tests."""
    row = finding.row
    if not np.isfinite(row["p"]):
        return "not tested"
    threshold = ALPHA / max(m, 1)
    if finding.one_sided:
        if row["p_holm"] < ALPHA:
            text = "supported"
        elif finding.reverse is not None and finding.reverse.p < threshold:
            return "opposite direction"
        else:
            text = _not_detected(row)
        start = finding.start_test
        already = start is not None and np.isfinite(start.p) and start.p < threshold
        return text + ("; already at generation 0" if already else "")
    above = row["a12"] > 0.5
    if row["p_holm"] < ALPHA:
        text = "supported" if above == finding.expected_above else "opposite direction"
    else:
        text = _not_detected(row)
    start = finding.start_test
    already = start is not None and np.isfinite(start.p) and start.p < threshold
    same_side = (row["a12_generation0"] > 0.5) == above
    return text + ("; already at arrival" if already and same_side and row["p_holm"] < ALPHA else "")


def _not_detected(row: dict) -> str:
    if not np.isfinite(row["detectable_a12"]):
        return "not detected, no effect detectable at this n"
    return "not detected"


def findings_frame(findings: Sequence[Finding]) -> pd.DataFrame:
    """The rows of ``findings`` as a table (``FINDING_COLUMNS``)."""
    return pd.DataFrame([f.row for f in findings], columns=FINDING_COLUMNS)


def findings_table(data: ExperimentData) -> pd.DataFrame:
    """The findings table (``FINDING_COLUMNS``): headline rows then secondary ones."""
    return findings_frame(headline_findings(data))


# ---- the report's view: each finding beside its start and its gain ----------------------------
def _means(groups: Sequence[np.ndarray]) -> str:
    return " | ".join(f"{v.mean():.3g}" if v.size else "-" for v in groups)


def findings_display(findings: Sequence[Finding]) -> pd.DataFrame:
    """Per finding: the groups compared (in the test's order), each group's mean at the
    compared generation, at the start (generation 0; a transition's arrival) and the mean
    evolved gain (compared minus start, over the same runs' means), with p_holm, the A12s
    and the verdict."""
    rows = []
    for f in findings:
        gain = [a.mean() - b.mean() if a.size and b.size else math.nan
                for a, b in zip(f.final, f.start, strict=True)]  # fmt: skip
        rows.append(
            {
                "question": f.row["question"],
                "groups": " | ".join(f.labels),
                "final (mean)": _means(f.final),
                "start (mean)": _means(f.start),
                "gain": " | ".join(f"{g:.3g}" for g in gain),
                "p_holm": f.row["p_holm"],
                "a12": f.row["a12"],
                "a12 at start": f.row["a12_generation0"],
                "detectable a12": f.row["detectable_a12"],
                "verdict": f.row["verdict"],
            }
        )
    return pd.DataFrame(rows)
