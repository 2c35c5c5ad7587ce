"""How many repetitions (and generations) the paper's comparisons need: a power analysis
from a pilot experiment's run-level outcomes that carries the pilot's uncertainty.

The paper's headline comparisons (``PAPER_COMPARISONS``), each a metric between two
treatments named by environment schedule and stiffness: land fitness S4 vs S1, water fitness
S1 vs S5, land->water vs water-only at S3, water->land vs land-only at S3, and actuation
frequency S1 vs S5 on land and in water. Those whose two treatments the pilot holds are
estimated. Each is tested in its family (``analysis.matching.families``: 10 stiffness pairs
per world on the paper's grid, a transition against its final world alone), so the
threshold is alpha / family size.

The model: the study's run values of a and b are normal with a common spread and a
standardized difference ``shift`` (means apart in standard deviations; A12 = Phi(shift /
sqrt 2)), and the study tests them as the report does with independent seeds (two-sided
Mann-Whitney U, scipy's exact p for small samples). For each comparison, at the generation
the report compares it at:

1. The pilot's standardized difference d (pooled standard deviation) and its lower
   confidence bound: the two-sided ``PILOT_CONFIDENCE`` (80%) interval of the shift from the
   noncentral t distribution of the pilot's t statistic; the bound is the end nearer 0 (0
   when the interval holds 0). For normal run values the true shift is below it in at most
   10% of pilots, so the power it predicts is above the true power in at most 10% of pilots.
2. The power at n: the share of ``RESAMPLES`` simulated studies of n runs per treatment at
   that bound whose p is below alpha / family (common random numbers across shifts, seeded,
   so the power grows with the shift and the same call gives the same answer).
   ``power_at_estimate`` is the same at the pilot's point estimate d: what a tool that
   trusts the pilot would say, for comparison only.
3. ``repetitions``: the smallest n in 2..max_n whose power reaches the target (bisection);
   None when max_n does not reach it, always when the bound is 0 ("no effect the pilot can
   vouch for").
4. ``detectable_a12``: the smallest effect (A12, on the side of 1) that a study of
   ``study_n`` runs per treatment detects with the target power in that family; NaN when no
   effect can be: the exact-p floor (``exact_floor``, the smallest p the rank test can give
   at n) is not below alpha / family.
5. ``generations``: along the pilot's run values at up to ``CHECKED_GENERATIONS``
   generations, the earliest from which the power at that n stays at the target up to the
   comparison's generation, as a count (index + 1); None when the last is below it.

The study must not reuse the pilot's runs: the ``study`` preset starts its seeds past the
pilot's (``evolution.treatments``), and every treatment of a preset has seeds of its own.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass
from functools import lru_cache

import numpy as np
import pandas as pd
from scipy import optimize, stats

from softevo.analysis.data import ExperimentData
from softevo.analysis.matching import families, family_size
from softevo.errors import UserError
from softevo.evolution import environments
from softevo.evolution.stats import mann_whitney, vargha_delaney

RESAMPLES = 2_000
PILOT_CONFIDENCE = 0.8
CHECKED_GENERATIONS = 12
MAX_N_LIMIT = 1_000
MIN_PILOT_RUNS = 2
MAX_SHIFT = 30.0  # standard deviations: a pilot without spread that separates is taken as this
DESIGN_NS = (3, 4, 5, 6, 7, 8, 10, 12, 15, 20, 30, 50)


@dataclass(frozen=True)
class PaperComparison:
    """A comparison of the paper: ``metric`` between treatments ``a`` and ``b``, each given as
    (environment schedule, stiffness in MPa)."""

    name: str
    metric: str
    a: tuple[str, float]
    b: tuple[str, float]


_LAND, _WATER = environments.PAPER
_LAND_WATER = environments.TRANSITION.join(environments.PAPER)
_WATER_LAND = environments.TRANSITION.join(environments.PAPER[::-1])
PAPER_COMPARISONS = (
    PaperComparison(f"{_LAND} fitness, S4 vs S1", "best_distance", (_LAND, 1.0), (_LAND, 0.001)),
    PaperComparison(f"{_WATER} fitness, S1 vs S5", "best_distance", (_WATER, 0.001), (_WATER, 10.0)),
    PaperComparison(
        f"{_LAND}->{_WATER} vs {_WATER} only, S3", "best_distance", (_LAND_WATER, 0.1), (_WATER, 0.1)
    ),
    PaperComparison(
        f"{_WATER}->{_LAND} vs {_LAND} only, S3", "best_distance", (_WATER_LAND, 0.1), (_LAND, 0.1)
    ),
    *(
        PaperComparison(
            f"frequency vs stiffness {environments.get(w).label}, S1 vs S5",
            "frequency",
            (w, 0.001),
            (w, 10.0),
        )
        for w in environments.PAPER
    ),
)


# ---- rank tests under the normal model ---------------------------------------------------------
def exact_floor(n_a: int, n_b: int | None = None, paired: bool = False) -> float:
    """The smallest two-sided exact p a rank test can give (no ties): 2 / C(n_a + n_b, n_a)
    for Mann-Whitney, 2 / 2^n for the signed-rank test of n pairs (capped at 1)."""
    if paired:
        return min(1.0, 2.0 / 2.0**n_a)
    return min(1.0, 2.0 / math.comb(n_a + (n_a if n_b is None else n_b), n_a))


@lru_cache(maxsize=64)
def _base_draws(n_a: int, n_b: int, paired: bool, resamples: int, seed: int):
    rng = np.random.default_rng([seed, n_a, n_b, int(paired)])
    a = rng.standard_normal((resamples, n_a))
    return a, (None if paired else rng.standard_normal((resamples, n_b)))


def rank_test_power(
    shift: float,
    n_a: int,
    n_b: int | None,
    alpha: float,
    paired: bool = False,
    resamples: int = RESAMPLES,
    seed: int = 0,
) -> float:
    """Share of ``resamples`` simulated studies whose two-sided p is below ``alpha``: a ~
    N(shift, 1) (n_a runs) against b ~ N(0, 1) (n_b runs) by Mann-Whitney U, or, ``paired``,
    n_a seed-matched differences ~ N(shift, 1) by the Wilcoxon signed-rank test."""
    n_b = n_a if n_b is None else n_b
    if exact_floor(n_a, n_b, paired) >= alpha:
        return 0.0
    a, b = _base_draws(n_a, n_b, paired, resamples, seed)
    if paired:
        p = stats.wilcoxon(a + shift, axis=1).pvalue
    else:
        p = stats.mannwhitneyu(a + shift, b, axis=1, alternative="two-sided").pvalue
    return float(np.mean(p < alpha))


def a12_of_shift(shift: float, paired: bool = False) -> float:
    """The A12 of a normal shift: Phi(shift / sqrt 2) between samples; Phi(shift) for paired
    differences (the share of pairs with a above b)."""
    return float(stats.norm.cdf(shift if paired else shift / math.sqrt(2)))


def detectable_shift(
    n_a: int, n_b: int | None, alpha: float, power: float = 0.8, paired: bool = False
) -> float:
    """The smallest shift (standard deviations) with ``rank_test_power`` >= ``power``; NaN
    when the exact-p floor makes every effect undetectable."""
    if rank_test_power(MAX_SHIFT, n_a, n_b, alpha, paired) < power:
        return float("nan")
    low, high = 0.0, MAX_SHIFT
    while high - low > 0.005:
        middle = (low + high) / 2
        if rank_test_power(middle, n_a, n_b, alpha, paired) >= power:
            high = middle
        else:
            low = middle
    return high


@lru_cache(maxsize=256)
def detectable_a12(
    n_a: int, n_b: int | None, alpha: float, power: float = 0.8, paired: bool = False
) -> float:
    """The smallest A12 (above 0.5; the mirror 1 - A12 alike) the design detects at
    ``power``; NaN when none can be (``detectable_shift``)."""
    shift = detectable_shift(n_a, n_b, alpha, power, paired)
    return float("nan") if math.isnan(shift) else a12_of_shift(shift, paired)


# ---- the pilot's effect and its uncertainty ----------------------------------------------------
def pilot_shift(a: np.ndarray, b: np.ndarray, confidence: float = PILOT_CONFIDENCE) -> tuple[float, float]:
    """(d, lower bound of |shift|): the pilot's standardized difference of means (pooled
    standard deviation) and the end nearer 0 of its two-sided ``confidence`` interval from
    the noncentral t (0 when the interval holds 0)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    df = a.size + b.size - 2
    pooled = math.sqrt(((a.size - 1) * a.var(ddof=1) + (b.size - 1) * b.var(ddof=1)) / df)
    difference = float(a.mean() - b.mean())
    if pooled == 0:
        return (0.0, 0.0) if difference == 0 else (math.copysign(MAX_SHIFT, difference), MAX_SHIFT)
    scale = math.sqrt(1 / a.size + 1 / b.size)
    t = min(abs(difference) / pooled / scale, MAX_SHIFT / scale)
    upper_cdf = 1 - (1 - confidence) / 2  # P(T <= |t|) at the interval's lower end

    def excess(ncp: float) -> float:  # falls with ncp; below 0 at ncp = t
        return float(stats.nct.cdf(t, df, ncp)) - upper_cdf

    width = 1.0
    while excess(t - width) <= 0:
        width *= 2
    low = optimize.brentq(excess, t - width, t)
    return difference / pooled, max(0.0, low) * scale


def pilot_power(a, b, n: int, alpha: float, seed: int = 0) -> tuple[float, float]:
    """(power at the pilot's lower bound, power at its point estimate) of a study of n runs
    per treatment at ``alpha`` (Mann-Whitney, independent seeds)."""
    estimate, low = pilot_shift(a, b)
    return (
        rank_test_power(low, n, n, alpha, seed=seed),
        rank_test_power(min(abs(estimate), MAX_SHIFT), n, n, alpha, seed=seed),
    )


def design_table(alpha: float, power: float = 0.8, ns=DESIGN_NS) -> pd.DataFrame:
    """Per n (runs per treatment): the exact-p floor of Mann-Whitney and of the signed-rank
    test, whether each can reach ``alpha``, and the smallest A12 each detects at ``power``."""
    rows = []
    for n in ns:
        rows.append(
            {
                "n": n,
                "alpha": alpha,
                "floor_mann_whitney": exact_floor(n, n),
                "detectable_a12_mann_whitney": detectable_a12(n, n, alpha, power),
                "floor_signed_rank": exact_floor(n, paired=True),
                "detectable_a12_signed_rank": detectable_a12(n, n, alpha, power, True),
            }
        )
    return pd.DataFrame(rows)


def first_feasible_n(alpha: float, paired: bool = False, max_n: int = MAX_N_LIMIT) -> int | None:
    """The smallest n whose exact-p floor is below ``alpha``."""
    return next((n for n in range(2, max_n + 1) if exact_floor(n, n, paired) < alpha), None)


# ---- the estimate ------------------------------------------------------------------------------
@dataclass(frozen=True)
class PowerEstimate:
    """The estimate for one comparison (see the module doc); ``repetitions`` and
    ``generations`` are None when the bounds do not reach the target power."""

    comparison: str
    metric: str
    a: str
    b: str
    generation: int
    pilot_runs_a: int
    pilot_runs_b: int
    pilot_seeds: str
    pilot_mean_a: float
    pilot_mean_b: float
    pilot_a12: float
    pilot_p: float
    pilot_shift: float
    shift_low: float
    a12_low: float
    family: str
    family_size: int
    alpha_bonferroni: float
    floor_n: int | None
    repetitions: int | None
    power: float
    power_at_estimate: float
    max_n: int
    study_n: int
    power_at_study_n: float
    detectable_a12: float
    generations: int | None
    pilot_generations: int

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class PowerSettings:
    """alpha before the correction, target power, the largest n tried, the family size
    (None: the comparison's family in the pilot, ``analysis.matching.families``), the planned
    study's runs per treatment (for its detectable effect), the seed."""

    alpha: float = 0.05
    power: float = 0.8
    max_n: int = 50
    family_size: int | None = None
    study_n: int = 7
    seed: int = 0

    def validate(self) -> None:
        if not 0 < self.alpha < 1:
            raise UserError(f"--alpha must be between 0 and 1 (got {self.alpha})")
        if not 0 < self.power < 1:
            raise UserError(f"--power must be between 0 and 1 (got {self.power})")
        if not MIN_PILOT_RUNS <= self.max_n <= MAX_N_LIMIT:
            raise UserError(f"--max-n must be within {MIN_PILOT_RUNS}..{MAX_N_LIMIT} (got {self.max_n})")
        if not MIN_PILOT_RUNS <= self.study_n <= MAX_N_LIMIT:
            raise UserError(f"--study-n must be within {MIN_PILOT_RUNS}..{MAX_N_LIMIT} (got {self.study_n})")
        if self.family_size is not None and self.family_size < 1:
            raise UserError(f"--family must be >= 1 (got {self.family_size})")


def treatment_named(treatments: pd.DataFrame, environment: str, stiffness_mpa: float) -> str | None:
    """The first treatment (creation order) of that environment schedule and stiffness."""
    same = treatments[
        (treatments["environment"] == environment)
        & np.isclose(treatments["stiffness_mpa"].astype(float), stiffness_mpa)
    ]
    return None if same.empty else str(same["name"].iloc[0])


def contained(data: ExperimentData) -> list[tuple[int, PaperComparison, str, str]]:
    """(index, comparison, name a, name b) of the paper's comparisons the experiment holds."""
    found = []
    for k, comparison in enumerate(PAPER_COMPARISONS):
        a, b = (treatment_named(data.treatments, *side) for side in (comparison.a, comparison.b))
        if a is not None and b is not None:
            found.append((k, comparison, a, b))
    return found


def missing(data: ExperimentData) -> list[str]:
    """Names of the paper's comparisons the experiment does not hold."""
    held = {k for k, *_ in contained(data)}
    return [c.name for k, c in enumerate(PAPER_COMPARISONS) if k not in held]


def needed_repetitions(
    power_at: Callable[[int], float], target: float, max_n: int
) -> tuple[int | None, float]:
    """(smallest n in 2..max_n with power_at(n) >= target, its power) by bisection; (None,
    power at max_n) when max_n falls short."""
    top = power_at(max_n)
    if top < target:
        return None, top
    low, high, best = MIN_PILOT_RUNS, max_n, top
    while low < high:
        middle = (low + high) // 2
        power = power_at(middle)
        if power >= target:
            high, best = middle, power
        else:
            low = middle + 1
    return high, best


def checked_generations(first: int, last: int, count: int = CHECKED_GENERATIONS) -> list[int]:
    """At most ``count`` generations spread evenly over first..last, both included."""
    if last <= first:
        return [last]
    return sorted({int(round(g)) for g in np.linspace(first, last, count)})


def power_generations(data: ExperimentData) -> list[int]:
    """The generations ``estimate_power`` reads run values at (for the loader)."""
    found: set[int] = set()
    for *_, a, b in contained(data):
        found.update(_checked(data, a, b))
    return sorted(found)


def _checked(data: ExperimentData, a: str, b: str) -> list[int]:
    generation = data.pair_generation(a, b)
    if generation is None:
        return []
    switches = data.treatments.set_index("name")["switch_at"]
    first = max([1, *(int(switches[n]) for n in (a, b) if pd.notna(switches[n]))])
    return checked_generations(min(first, generation), generation)


def _pilot_values(data: ExperimentData, comparison: PaperComparison, a: str, b: str, generation: int):
    values = data.run_values(generation)
    out = []
    for name in (a, b):
        series = values.loc[values["treatment"] == name, comparison.metric].dropna().to_numpy(float)
        if series.size < MIN_PILOT_RUNS:
            raise UserError(
                f"{comparison.name}: treatment {name!r} has {series.size} run(s) with "
                f"{comparison.metric} at generation {generation}; a pilot needs at least "
                f"{MIN_PILOT_RUNS} per treatment"
            )
        out.append(series)
    return out


def _family(data: ExperimentData, a: str, b: str, settings: PowerSettings) -> tuple[str, int]:
    question = next(p.question for p in families(data.treatments) if {p.a, p.b} == {a, b})
    return question, settings.family_size or max(1, family_size(data.treatments, question))


def pilot_seeds(data: ExperimentData, names: tuple[str, ...]) -> str:
    """The seeds of the pilot's runs of ``names``, as ``0..2`` ranges joined by commas."""
    seeds = sorted({int(s) for s in data.runs.loc[data.runs["treatment"].isin(names), "seed"]})
    ranges, start = [], None
    for k, seed in enumerate(seeds):
        start = seed if start is None else start
        if k + 1 == len(seeds) or seeds[k + 1] != seed + 1:
            ranges.append(f"{start}" if start == seed else f"{start}..{seed}")
            start = None
    return ", ".join(ranges)


def estimate_power(
    data: ExperimentData,
    settings: PowerSettings = PowerSettings(),
    on_step: Callable[[str], None] | None = None,
) -> list[PowerEstimate]:
    """The estimate for each of the paper's comparisons the pilot ``data`` holds (see the
    module doc). UserError when it holds none, or a comparison lacks pilot runs."""
    settings.validate()
    if data.generations.empty:
        raise UserError(f"experiment e{data.experiment.get('id')} has no stored generation yet")
    found = contained(data)
    if not found:
        raise UserError(
            f"experiment e{data.experiment.get('id')} holds none of the paper's comparisons "
            "(each needs two treatments, e.g. land at 1 and at 0.001 MPa; see `softevo power --help`)"
        )
    step = on_step or (lambda _text: None)
    return [_estimate(data, settings, step, k, comparison, a, b) for k, comparison, a, b in found]


def _estimate(data, settings, step, k, comparison, a, b) -> PowerEstimate:
    generation = data.pair_generation(a, b)
    if generation is None:
        raise UserError(f"{comparison.name}: no run of {a!r} and {b!r} has stored a generation yet")
    pilot_a, pilot_b = _pilot_values(data, comparison, a, b, generation)
    family, size = _family(data, a, b, settings)
    alpha = settings.alpha / size
    estimate, low = pilot_shift(pilot_a, pilot_b)

    def power_at(n: int, shift: float = low) -> float:
        step(f"{comparison.name}: n={n}")
        return rank_test_power(shift, n, n, alpha, seed=settings.seed)

    repetitions, power = needed_repetitions(power_at, settings.power, settings.max_n)
    n = repetitions or settings.max_n
    side = 1.0 if estimate >= 0 else -1.0
    return PowerEstimate(
        comparison=comparison.name,
        metric=comparison.metric,
        a=a,
        b=b,
        generation=generation,
        pilot_runs_a=int(pilot_a.size),
        pilot_runs_b=int(pilot_b.size),
        pilot_seeds=pilot_seeds(data, (a, b)),
        pilot_mean_a=float(pilot_a.mean()),
        pilot_mean_b=float(pilot_b.mean()),
        pilot_a12=vargha_delaney(pilot_a, pilot_b),
        pilot_p=mann_whitney(pilot_a, pilot_b)[1],
        pilot_shift=estimate,
        shift_low=low,
        a12_low=a12_of_shift(side * low),
        family=family,
        family_size=size,
        alpha_bonferroni=alpha,
        floor_n=first_feasible_n(alpha),
        repetitions=repetitions,
        power=power,
        power_at_estimate=rank_test_power(min(abs(estimate), MAX_SHIFT), n, n, alpha, seed=settings.seed),
        max_n=settings.max_n,
        study_n=settings.study_n,
        power_at_study_n=power_at(settings.study_n),
        detectable_a12=detectable_a12(settings.study_n, settings.study_n, alpha, settings.power),
        generations=_needed_generations(data, comparison, a, b, n, alpha, settings, step),
        pilot_generations=generation + 1,
    )


def _needed_generations(data, comparison, a, b, n, alpha, settings, step) -> int | None:
    """Earliest checked generation (as a count) from which the power at n stays >= target."""
    needed = None
    for generation in reversed(_checked(data, a, b)):
        values = data.run_values(generation)
        samples = [
            values.loc[values["treatment"] == t, comparison.metric].dropna().to_numpy(float) for t in (a, b)
        ]
        if min(s.size for s in samples) < MIN_PILOT_RUNS:
            break
        step(f"{comparison.name}: generation {generation}")
        if pilot_power(*samples, n, alpha, seed=settings.seed)[0] < settings.power:
            break
        needed = generation + 1
    return needed


def estimate_steps(data: ExperimentData, settings: PowerSettings) -> int:
    """An upper bound of the power evaluations ``estimate_power`` makes (for a progress bar)."""
    per = int(np.ceil(np.log2(max(2, settings.max_n)))) + 3
    return sum(per + len(_checked(data, a, b)) for _, _, a, b in contained(data))
