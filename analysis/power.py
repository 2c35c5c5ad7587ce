"""How many repetitions (and generations) the paper's comparisons need: a power analysis
from a pilot experiment's run-level outcomes, by resampling its runs.

The paper's headline comparisons (``PAPER_COMPARISONS``), each a metric between two
treatments named by environment schedule and stiffness: land fitness S4 vs S1, water fitness
S1 vs S5, land->water vs water-only at S3, water->land vs land-only at S3, and actuation
frequency S1 vs S5 on land and in water (the ends of the stiffness range: does frequency
move with stiffness). Those whose two treatments the pilot holds are estimated.

For each, at the generation the report compares it at (``analysis.matching``):

1. The pilot's run values (one per run: best distance, or population mean of the trait).
2. A simulated study of n repetitions per treatment draws n runs from each treatment's pilot
   runs with replacement and adds Gaussian noise of the treatment's kernel bandwidth
   (Silverman's rule, 0.9 min(sd, IQR/1.34) m^(-1/5) over its m pilot runs): a smoothed
   bootstrap, so that a study is not a copy of the few pilot values and ties do not pile
   up. ``RESAMPLES`` studies per n, each tested as the report does (two-sided Mann-Whitney
   U, scipy's choice of exact or asymptotic p); the power at n is the share with
   p < alpha / m, m the comparisons in the metric's Bonferroni family (the treatment pairs
   of the pilot, ``comparison_pairs``, unless given).
3. ``repetitions``: the smallest n in 2..max_n whose power reaches the target (bisection,
   taking power to grow with n; None when max_n does not reach it).
4. ``generations``: from the run values along the pilot's generations (its fitness curves
   for the fitness comparisons), the earliest checked generation from which the power at
   that n (max_n when none reached the target) stays at or above the target up to the
   comparison's generation, as a count of generations (index + 1); None when the pilot's
   last checked generation is below the target. At most ``CHECKED_GENERATIONS`` generations
   are checked, spread evenly from generation 1 (for a transition, from its switch) on.

Every draw comes from a generator seeded by (seed, comparison, n or generation), so the
same pilot and seed give the same estimate. Work is bounded: at most about
(log2(max_n) + 1 + CHECKED_GENERATIONS) * RESAMPLES tests of size max_n per comparison.

A pilot of a few runs describes its treatments' spread poorly: the estimate is as good as
the pilot, and a pilot of a smaller scale (fewer generations, smaller populations) predicts
a study of that scale. Use it to size a study at the pilot's scale.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass

import numpy as np
import pandas as pd
from scipy import stats

from softevo.analysis.data import ExperimentData
from softevo.analysis.matching import comparison_pairs
from softevo.errors import UserError
from softevo.evolution.stats import mann_whitney, vargha_delaney

RESAMPLES = 2_000
CHECKED_GENERATIONS = 12
MAX_N_LIMIT = 1_000
MIN_PILOT_RUNS = 2


@dataclass(frozen=True)
class PaperComparison:
    """A comparison of the paper: ``metric`` between treatments ``a`` and ``b``, each given as
    (environment schedule, stiffness in MPa)."""

    name: str
    metric: str
    a: tuple[str, float]
    b: tuple[str, float]


PAPER_COMPARISONS = (
    PaperComparison("land fitness, S4 vs S1", "best_distance", ("land", 1.0), ("land", 0.001)),
    PaperComparison("water fitness, S1 vs S5", "best_distance", ("water", 0.001), ("water", 10.0)),
    PaperComparison("land->water vs water only, S3", "best_distance", ("land-water", 0.1), ("water", 0.1)),
    PaperComparison("water->land vs land only, S3", "best_distance", ("water-land", 0.1), ("land", 0.1)),
    PaperComparison("frequency vs stiffness on land, S1 vs S5", "frequency", ("land", 0.001), ("land", 10.0)),
    PaperComparison(
        "frequency vs stiffness in water, S1 vs S5", "frequency", ("water", 0.001), ("water", 10.0)
    ),
)


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
    pilot_mean_a: float
    pilot_mean_b: float
    pilot_a12: float
    pilot_p: float
    alpha_bonferroni: float
    family_size: int
    repetitions: int | None
    power: float
    max_n: int
    generations: int | None
    pilot_generations: int

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class PowerSettings:
    """alpha before the correction, target power, the largest n tried, the Bonferroni
    family size (None: the pilot's treatment pairs), the seed."""

    alpha: float = 0.05
    power: float = 0.8
    max_n: int = 50
    family_size: int | None = None
    seed: int = 0

    def validate(self) -> None:
        if not 0 < self.alpha < 1:
            raise UserError(f"--alpha must be between 0 and 1 (got {self.alpha})")
        if not 0 < self.power < 1:
            raise UserError(f"--power must be between 0 and 1 (got {self.power})")
        if not MIN_PILOT_RUNS <= self.max_n <= MAX_N_LIMIT:
            raise UserError(f"--max-n must be within {MIN_PILOT_RUNS}..{MAX_N_LIMIT} (got {self.max_n})")
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


def bandwidth(values: np.ndarray) -> float:
    """Silverman's rule of thumb for a Gaussian kernel over ``values`` (ddof 1); a tiny
    positive width when the values do not spread (so ties are broken at random)."""
    values = np.asarray(values, float)
    sd = float(values.std(ddof=1)) if values.size > 1 else 0.0
    q75, q25 = np.percentile(values, [75, 25])
    spread = min(sd, (q75 - q25) / 1.34) or sd
    if spread > 0:
        return 0.9 * spread * values.size ** (-0.2)
    return 1e-9 * max(1.0, float(np.abs(values).max(initial=0.0)))


def simulated_power(
    a: np.ndarray, b: np.ndarray, n: int, alpha: float, rng: np.random.Generator, resamples: int = RESAMPLES
) -> float:
    """Share of ``resamples`` simulated studies of n runs per treatment (smoothed bootstrap
    of the pilot runs ``a`` and ``b``) whose two-sided Mann-Whitney p is below ``alpha``."""
    draws = []
    for values in (np.asarray(a, float), np.asarray(b, float)):
        picks = values[rng.integers(0, values.size, (resamples, n))]
        draws.append(picks + bandwidth(values) * rng.standard_normal((resamples, n)))
    p = stats.mannwhitneyu(draws[0], draws[1], axis=1, alternative="two-sided").pvalue
    return float(np.mean(p < alpha))


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
    family = settings.family_size or len(comparison_pairs(data.treatments))
    alpha = settings.alpha / family
    step = on_step or (lambda _text: None)
    results = []
    for k, comparison, a, b in found:
        generation = data.pair_generation(a, b)
        if generation is None:
            raise UserError(f"{comparison.name}: no run of {a!r} and {b!r} has stored a generation yet")
        pilot_a, pilot_b = _pilot_values(data, comparison, a, b, generation)

        def power_at(n: int, values=(pilot_a, pilot_b), k=k, name=comparison.name) -> float:
            step(f"{name}: n={n}")
            return simulated_power(*values, n, alpha, np.random.default_rng([settings.seed, k, n]))

        repetitions, power = needed_repetitions(power_at, settings.power, settings.max_n)
        generations = _needed_generations(
            data, comparison, k, a, b, repetitions or settings.max_n, alpha, settings, step
        )
        results.append(
            PowerEstimate(
                comparison=comparison.name,
                metric=comparison.metric,
                a=a,
                b=b,
                generation=generation,
                pilot_runs_a=int(pilot_a.size),
                pilot_runs_b=int(pilot_b.size),
                pilot_mean_a=float(pilot_a.mean()),
                pilot_mean_b=float(pilot_b.mean()),
                pilot_a12=vargha_delaney(pilot_a, pilot_b),
                pilot_p=mann_whitney(pilot_a, pilot_b)[1],
                alpha_bonferroni=alpha,
                family_size=family,
                repetitions=repetitions,
                power=power,
                max_n=settings.max_n,
                generations=generations,
                pilot_generations=generation + 1,
            )
        )
    return results


def _needed_generations(data, comparison, k, a, b, n, alpha, settings, step) -> int | None:
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
        rng = np.random.default_rng([settings.seed, k, MAX_N_LIMIT + 1 + generation])
        if simulated_power(*samples, n, alpha, rng) < settings.power:
            break
        needed = generation + 1
    return needed


def estimate_steps(data: ExperimentData, settings: PowerSettings) -> int:
    """An upper bound of the power evaluations ``estimate_power`` makes (for a progress bar)."""
    per = int(np.ceil(np.log2(max(2, settings.max_n)))) + 2
    return sum(per + len(_checked(data, a, b)) for _, _, a, b in contained(data))


def power_table(estimates: list[PowerEstimate]) -> pd.DataFrame:
    """The estimates as a DataFrame (one row each)."""
    return pd.DataFrame([e.to_dict() for e in estimates])
