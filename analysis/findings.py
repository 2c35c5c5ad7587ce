"""The headline findings: one test per hypothesis of the paper, its verdict, power and
intervals, by code (issues 46 and 55), as a table (``findings.csv``, ``FINDING_COLUMNS``).
The verdicts' vocabulary is defined in docs/results/README.md; this module applies it.

Treatments are found by world and stiffness (``analysis.power.treatment_named``), so only
the findings the experiment holds are returned. No test ever pairs land with water.

Measures, one value per run (``MEASURES``): ``best_distance``, the run's best distance in
its final generation (the paper's measure); ``distance_gain``, that minus the run's best at
generation 0, and ``distance_log_gain``, the log of their ratio; ``frequency_change``, the
mean actuation frequency of the run's final population minus its generation 0's (what
evolution did to frequency: at generation 0 frequency depends on the genome alone, not on
stiffness); ``frequency``, the final population's mean frequency.

Three families (``family``), each Holm-corrected on its own:

- ``primary``: one declared measure per hypothesis. The four stiffness trends (land distance
  rises S2..S5: the paper calls land S1 non-functional; water distance falls S1..S5; land
  frequency falls; water frequency rises), each a Jonckheere-Terpstra test one-sided in the
  paper's direction (``analysis.rank_tests``; exact p without ties), on ``best_distance``
  for distance and ``frequency_change`` for frequency, at the last generation every run of
  the trend's treatments stored; and each transition against the static control of its
  final world at equal total generations (the paper's contrast), two-sided Mann-Whitney
  (the paper states no direction beforehand) on ``best_distance``.
- ``gain``: the two distance trends on ``distance_gain`` and on ``distance_log_gain``.
- ``secondary``: the frequency trends on the final level (``frequency``), and each
  transition at equal time in its final world (the control at the transition's final
  generation less its arrival generation).

Columns beside the test: ``a12`` (Vargha-Delaney; for a trend the level the hypothesis puts
highest over the one it puts lowest, for a transition the transition over its control)
with its bootstrap 95% interval (``a12_low``, ``a12_high``: ``analysis.design``);
``a12_generation0`` and ``p_generation0``, the same A12 and test on the level measure at
generation 0 (for a transition: its arrival in the final world against the control's
generation 0); ``adjacent_a12``, each level over the one before it in the hypothesis'
order; ``holm_threshold``, the level Holm's step-down procedure holds the row's p to;
``power``, the design as run at the effect seen, ``detectable_a12`` the smallest effect it
detects (a linear trend's extreme-level A12, or a shift's) and ``runs_needed`` /
``runs_needed_a12_071`` the runs a treatment a design needs at the effect seen and at A12
0.71, each at 80% power and at the family's strictest threshold alpha / m (conservative
for all but its smallest p).

``verdict`` (the vocabulary, ``VERDICTS``; each row's verdict starts with one of them):
``reversed`` when the test against the paper's direction is significant (at alpha / m);
otherwise for a trend ``evolved`` when its primary test and its gain test both hold after
Holm (for frequency the primary measure is the gain), ``present in random bodies`` when the
trend holds at generation 0 (Holm over the family's generation-0 tests) and the gain test
does not, else ``not detected``; for a transition ``evolved`` when it holds after Holm in
the paper's direction. A trend whose adjacent levels turn against the hypothesis (an
adjacent one-sided Mann-Whitney p below alpha, uncorrected) says so in its verdict.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from softevo.analysis import design
from softevo.analysis.data import ExperimentData
from softevo.analysis.matching import arrival_generation, last_common_generation
from softevo.analysis.power import treatment_named
from softevo.analysis.rank_tests import RankTest, holm, jonckheere_terpstra, mann_whitney
from softevo.analysis.run_summary import best_distance_at
from softevo.analysis.stats_tables import ALPHA, MIN_TESTED_RUNS, POWER, few_runs_text
from softevo.evolution import environments
from softevo.evolution.stats import vargha_delaney

FINDING_COLUMNS = [
    "question", "family", "measure", "test", "generation", "n", "statistic", "p", "p_holm",
    "holm_threshold", "a12", "a12_low", "a12_high", "a12_generation0", "p_generation0",
    "adjacent_a12", "power", "detectable_a12", "runs_needed", "runs_needed_a12_071", "verdict",
]  # fmt: skip
STIFFNESS_LEVELS_MPA = {"S1": 0.001, "S2": 0.01, "S3": 0.1, "S4": 1.0, "S5": 10.0}
MEASURES = {
    "best_distance": "best distance in the final generation, per run (voxel lengths)",
    "distance_gain": "best distance, final minus generation 0, per run (voxel lengths)",
    "distance_log_gain": "log(best distance final / generation 0), per run",
    "frequency_change": "population's mean actuation frequency, final minus generation 0, per run (Hz)",
    "frequency": "mean actuation frequency of the final population, per run (Hz)",
}
LEVEL_OF = {  # a measure's value at generation 0 (the start), for the generation-0 test
    "best_distance": "best_distance", "distance_gain": "best_distance", "distance_log_gain": "best_distance",
    "frequency_change": "frequency", "frequency": "frequency",
}  # fmt: skip
PRIMARY, GAIN, SECONDARY_FAMILY = "primary", "gain", "secondary"
FAMILIES = (PRIMARY, GAIN, SECONDARY_FAMILY)
VERDICTS = ("evolved", "present in random bodies", "not detected", "reversed")
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
    metric: str  # "distance" or "frequency"
    levels: tuple[str, ...]


TRENDS = (
    Trend(f"{_LAND} distance rises with stiffness", _LAND, "distance", ("S2", "S3", "S4", "S5")),
    Trend(f"{_WATER} distance falls with stiffness", _WATER, "distance", ("S5", "S4", "S3", "S2", "S1")),
    Trend(f"{_LAND} frequency falls with stiffness", _LAND, "frequency", ("S5", "S4", "S3", "S2")),
    Trend(f"{_WATER} frequency rises with stiffness", _WATER, "frequency", ("S1", "S2", "S3", "S4", "S5")),
)
TREND_MEASURES = {  # (family, measure) per trend metric, the primary first
    "distance": ((PRIMARY, "best_distance"), (GAIN, "distance_gain"), (GAIN, "distance_log_gain")),
    "frequency": ((PRIMARY, "frequency_change"), (SECONDARY_FAMILY, "frequency")),
}
GAIN_OF = {"best_distance": "distance_gain", "frequency": "frequency_change"}  # the verdict's gain test
CHANGES = ("distance_gain", "distance_log_gain", "frequency_change")  # measures of a run's change from 0


@dataclass
class Finding:
    """One row of the table and the groups behind it: ``labels`` (treatment names, in the
    order the hypothesis says values rise for a trend; transition, control for a contrast),
    ``final`` and ``start`` (their runs' values of the measure, and of its level at the
    start), ``generations`` (compared, start) per group."""

    row: dict
    labels: tuple[str, ...] = ()
    final: tuple[np.ndarray, ...] = ()
    start: tuple[np.ndarray, ...] = ()
    generations: tuple[tuple[int | None, int | None], ...] = ()
    one_sided: bool = True
    expected_above: bool = True  # a two-sided contrast: the paper's direction
    start_test: RankTest | None = field(default=None)
    reverse: RankTest | None = field(default=None)
    trend: Trend | None = None
    levels: tuple[str, ...] = ()

    @property
    def family(self) -> str:
        return self.row["family"]

    @property
    def measure(self) -> str:
        return self.row["measure_key"]


# ---- run values ----------------------------------------------------------------------------
def run_series(data: ExperimentData, name: str, generation: int | None, metric: str) -> pd.Series:
    """One value per run of treatment ``name`` at ``generation``, by run_id: its best
    distance (the generation summary) or its population's mean |frequency|; runs without
    it left out."""
    if generation is None:
        return pd.Series(dtype=float)
    run_ids = data.runs.loc[data.runs["treatment"] == name, "run_id"]
    if metric in ("best_distance", "distance"):
        values = best_distance_at(data, generation).reindex(run_ids)
    else:
        members = data.populations_at(generation)
        members = members[members["run_id"].isin(run_ids)]
        values = members["frequency"].abs().groupby(members["run_id"]).mean().reindex(run_ids)
    values = values.astype(float)
    return values[np.isfinite(values.to_numpy())]


def run_values(data: ExperimentData, name: str, generation: int | None, metric: str) -> np.ndarray:
    """``run_series`` as an array of the measures ``MEASURES`` (gains: final minus, or the log
    of the ratio to, the same run's value at generation 0), in run order."""
    level = LEVEL_OF.get(metric, metric)
    final = run_series(data, name, generation, level)
    if metric in CHANGES:
        start = run_series(data, name, 0, level)
        final, start = final.align(start, join="inner")
        if metric == "distance_log_gain":
            with np.errstate(divide="ignore", invalid="ignore"):
                values = np.log(final.to_numpy() / start.to_numpy())
        else:
            values = final.to_numpy() - start.to_numpy()
        return values[np.isfinite(values)]
    return final.to_numpy(float)


def _a12(high: np.ndarray, low: np.ndarray) -> float:
    return vargha_delaney(high, low) if high.size and low.size else math.nan


# ---- the findings ----------------------------------------------------------------------------
def trend_findings(data: ExperimentData, trend: Trend) -> list[Finding]:
    """The trend's tests, one per measure of ``TREND_MEASURES``, over the levels the
    experiment holds (none with fewer than two)."""
    found = [(level, treatment_named(data.treatments, trend.world, STIFFNESS_LEVELS_MPA[level]))
             for level in trend.levels]  # fmt: skip
    found = [(level, name) for level, name in found if name is not None]
    if len(found) < 2:
        return []
    names = [name for _, name in found]
    levels = tuple(level for level, _ in found)
    generation = last_common_generation(data.runs, names)
    ordered = sorted(levels, key=lambda s: STIFFNESS_LEVELS_MPA[s])
    findings = []
    for family, measure in TREND_MEASURES[trend.metric]:
        final = tuple(run_values(data, n, generation, measure) for n in names)
        start = tuple(run_values(data, n, 0, LEVEL_OF[measure]) for n in names)
        if sum(v.size > 0 for v in final) < 2:
            continue
        test, start_test = jonckheere_terpstra(final), jonckheere_terpstra(start)
        label = {PRIMARY: "", SECONDARY_FAMILY: f" {SECONDARY}", GAIN: " (gain)"}[family]
        label = " (log gain)" if measure == "distance_log_gain" else label
        question = f"{trend.question} ({', '.join(ordered)}){label}"
        row = _row(question, family, measure, f"{JT} ({test.method})", generation, final, test,
                   _a12(final[-1], final[0]), _a12(start[-1], start[0]), start_test)  # fmt: skip
        findings.append(Finding(row, tuple(names), final, start, tuple((generation, 0) for _ in names),
                                start_test=start_test, reverse=jonckheere_terpstra(final, "decreasing"),
                                trend=trend, levels=levels))  # fmt: skip
    return findings


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
        paper = _contrast(
            data, treatment, control, (end, arrival), (end, 0), "equal total generations", PRIMARY
        )
        equal = _contrast(data, treatment, control, (end, arrival), (end - arrival, 0),
                          f"equal time in {world} {SECONDARY}", SECONDARY_FAMILY)  # fmt: skip
        found.append((paper, equal))
    return found


def _contrast(data, treatment, control: str, at: tuple[int, int], control_at: tuple[int, int], how: str,
              family: str) -> Finding:
    name = treatment["name"]
    final, start = (
        (run_values(data, name, g, "best_distance"), run_values(data, control, c, "best_distance"))
        for g, c in zip(at, control_at, strict=True)
    )
    test, start_test = mann_whitney(*final), mann_whitney(*start)
    question = f"{name} vs {control}, {how}: generation {at[0]} vs {control_at[0]}"
    expected_above = environments.final(treatment["environment"]) == _LAND  # the paper: water->land better
    row = _row(question, family, "best_distance", f"{MW} ({test.method})", at[0], final, test,
               _a12(*final), _a12(*start), start_test)  # fmt: skip
    return Finding(row, (name, control), final, start, (at, control_at), one_sided=False,
                   expected_above=expected_above, start_test=start_test)  # fmt: skip


def _row(question, family, measure, test_name, generation, groups, test: RankTest, a12: float,
         a12_start: float, start_test: RankTest) -> dict:
    return {"question": question, "family": family, "measure": MEASURES[measure], "measure_key": measure,
            "test": test_name, "generation": generation, "n": "+".join(str(v.size) for v in groups),
            "statistic": test.statistic, "p": test.p, "p_holm": math.nan, "holm_threshold": math.nan,
            "a12": a12, "a12_low": math.nan, "a12_high": math.nan, "a12_generation0": a12_start,
            "p_generation0": start_test.p, "adjacent_a12": "", "power": math.nan,
            "detectable_a12": math.nan, "runs_needed": None, "runs_needed_a12_071": None,
            "verdict": ""}  # fmt: skip


def headline_findings(data: ExperimentData, design_figures: bool = True) -> list[Finding]:
    """Every finding the experiment holds: the primary family (the trends' primary tests,
    then the transitions' paper contrasts), the gain family, the secondary family; each
    Holm-corrected, with intervals, power and verdict (module doc). ``design_figures=False``
    leaves power, detectable A12 and runs needed out (NaN): they take seconds."""
    trends = [f for t in TRENDS for f in trend_findings(data, t)]
    transitions = transition_findings(data)
    findings = trends + [paper for paper, _ in transitions] + [equal for _, equal in transitions]
    for finding in findings:  # fewer runs: described, not tested (issue 59.3)
        if not tested_groups(finding):
            finding.row.update(statistic=math.nan, p=math.nan, p_generation0=math.nan)
    by_family = {family: [f for f in findings if f.family == family] for family in FAMILIES}
    for family in by_family.values():
        _adjust(family, design_figures)
    for finding in findings:
        finding.row["verdict"] = verdict(finding, by_family[finding.family], findings)
    return [f for family in FAMILIES for f in by_family[family]]


def tested_groups(finding: Finding) -> bool:
    """Whether each group of ``finding`` that holds runs has at least ``MIN_TESTED_RUNS``."""
    sizes = [g.size for g in finding.final if g.size]
    return bool(sizes) and min(sizes) >= MIN_TESTED_RUNS


def _adjust(family: list[Finding], design_figures: bool) -> None:
    p_values = [f.row["p"] for f in family]
    m = int(np.isfinite(p_values).sum())
    for finding, p_holm, threshold, start_holm in zip(
        family, holm(p_values), design.holm_thresholds(p_values, ALPHA),
        holm([f.row["p_generation0"] if f.one_sided else math.nan for f in family]), strict=True
    ):
        row = finding.row
        row["p_holm"], row["holm_threshold"], row["p_generation0_holm"] = p_holm, threshold, start_holm
        high, low = (finding.final[-1], finding.final[0]) if finding.one_sided else finding.final
        if tested_groups(finding):  # no interval below MIN_TESTED_RUNS
            row["a12_low"], row["a12_high"] = design.a12_interval(high, low)  # as ``a12``
        if finding.trend is not None:
            row["adjacent_a12"] = adjacent_text(finding)
        if design_figures and m:
            row.update(design_row(finding, ALPHA / m))


def rising_groups(finding: Finding) -> tuple[np.ndarray, ...]:
    """The finding's groups in the order its hypothesis says values rise (a transition the
    paper expects below its control first)."""
    return finding.final[::-1] if not finding.one_sided and finding.expected_above else finding.final


def design_row(finding: Finding, alpha: float) -> dict:
    """Power at the effect seen, the detectable A12 and the runs a group needed at the
    effect seen and at A12 0.71, at ``alpha`` (``analysis.design``)."""
    groups = [g for g in rising_groups(finding) if g.size]
    if len(groups) < 2 or min(g.size for g in groups) < MIN_TESTED_RUNS:
        return {}
    two_sided, n = not finding.one_sided, min(g.size for g in groups)
    seen = design.observed_effect(groups)
    return {
        "power": design.power(seen, n, alpha, two_sided),
        "detectable_a12": design.detectable_a12(len(groups), n, alpha, two_sided),
        "runs_needed": design.runs_needed(seen, alpha, two_sided, POWER),
        "runs_needed_a12_071": design.runs_needed(design.linear_effect(len(groups)), alpha, two_sided, POWER),
    }


def adjacent_text(finding: Finding) -> str:
    """Each level over the one before it in the hypothesis' order: ``S2>S3 0.81; ...``."""
    pairs = zip(finding.levels[:-1], finding.levels[1:], strict=True)
    values = design.adjacent_a12s(finding.final)
    return "; ".join(f"{b} over {a} {v:.2f}" for (a, b), v in zip(pairs, values, strict=True))


def turns(finding: Finding) -> list[str]:
    """The adjacent levels where the trend turns against the hypothesis: the one-sided
    Mann-Whitney test of the later level below the earlier one, p < alpha (uncorrected)."""
    out = []
    for (a, b), low, high in zip(zip(finding.levels[:-1], finding.levels[1:], strict=True),
                                 finding.final[:-1], finding.final[1:], strict=True):  # fmt: skip
        if low.size and high.size:
            test = mann_whitney(high, low, "less")
            if test.p < ALPHA:
                out.append(f"turns between {a} and {b} (A12 {_a12(high, low):.2f}, one-sided p {test.p:.2g})")
    return out


def _holds(finding: Finding | None) -> bool:
    return finding is not None and np.isfinite(finding.row["p_holm"]) and finding.row["p_holm"] < ALPHA


def _partner(finding: Finding, findings: Sequence[Finding], measure: str) -> Finding | None:
    return next((f for f in findings if f.trend == finding.trend and f.measure == measure), None)


def verdict(finding: Finding, family: Sequence[Finding], findings: Sequence[Finding]) -> str:
    """The finding's verdict (``VERDICTS``, module doc), with its reasons."""
    row = finding.row
    if not np.isfinite(row["p"]):
        sizes = [g.size for g in finding.final if g.size]
        few = sizes and min(sizes) < MIN_TESTED_RUNS
        return f"not detected; {few_runs_text(min(sizes))}" if few else "not detected; not tested"
    m = max(int(np.isfinite([f.row["p"] for f in family]).sum()), 1)
    p = f"p_holm {row['p_holm']:.2g}"
    if not finding.one_sided:
        above = row["a12"] > 0.5
        if _holds(finding):
            direction = "evolved" if above == finding.expected_above else "reversed"
            return f"{direction}; {p}, A12 {row['a12']:.2f}"
        return f"not detected; {p}"
    if finding.reverse is not None and finding.reverse.p < ALPHA / m:
        text = (f"reversed; the test against the paper's direction p {finding.reverse.p:.2g} "
                f"< {ALPHA / m:.2g}")
    else:
        gain = (finding if finding.measure in CHANGES
                else _partner(finding, findings, GAIN_OF[finding.measure]))
        start_holds = (np.isfinite(row.get("p_generation0_holm", math.nan))
                       and row["p_generation0_holm"] < ALPHA)
        gain_text = "" if gain is finding or gain is None else f", its gain p_holm {gain.row['p_holm']:.2g}"
        start_text = f"generation 0 p {row['p_generation0']:.2g}"
        if _holds(finding) and _holds(gain):
            text = f"evolved; {p}{gain_text}; {start_text}"
        elif start_holds and not _holds(gain):
            text = (f"present in random bodies; {start_text} (Holm {row['p_generation0_holm']:.2g}), "
                    f"{p}{gain_text}")
        else:
            text = f"not detected; {p}{gain_text}; {start_text}"
    return "; ".join([text, *turns(finding)])


def findings_frame(findings: Sequence[Finding]) -> pd.DataFrame:
    """The rows of ``findings`` as a table (``FINDING_COLUMNS``)."""
    frame = pd.DataFrame([f.row for f in findings], columns=FINDING_COLUMNS)
    for column in ("runs_needed", "runs_needed_a12_071"):
        frame[column] = pd.array(frame[column], dtype="Int64")
    return frame


def findings_table(data: ExperimentData, design_figures: bool = True) -> pd.DataFrame:
    """The findings table (``FINDING_COLUMNS``): the primary family, the gain family, the
    secondary family."""
    return findings_frame(headline_findings(data, design_figures))


# ---- the report's view: each finding beside its start and its gain ----------------------------
def _means(groups: Sequence[np.ndarray]) -> str:
    return " | ".join(f"{v.mean():.3g}" if v.size else "-" for v in groups)


def findings_display(findings: Sequence[Finding]) -> pd.DataFrame:
    """Per finding: the groups compared (in the test's order), each group's mean of the
    measure at the compared generation and of its level at the start (generation 0; a
    transition's arrival), with p_holm, A12 and its interval, A12 at the start, the power
    of the design, the runs a treatment it would need, and the verdict."""
    rows = []
    for f in findings:
        row = f.row
        needed = "-" if pd.isna(row["runs_needed"]) else str(row["runs_needed"])
        rows.append(
            {
                "question": row["question"],
                "groups": " | ".join(f.labels),
                "measure (mean)": _means(f.final),
                "start (mean)": _means(f.start),
                "p_holm": row["p_holm"],
                "a12 [95%]": f"{row['a12']:.2f} [{row['a12_low']:.2f}, {row['a12_high']:.2f}]",
                "a12 at start": row["a12_generation0"],
                "power": row["power"],
                "runs needed (seen | 0.71)": f"{needed} | {row['runs_needed_a12_071']}",
                "verdict": row["verdict"],
            }
        )
    return pd.DataFrame(rows)
