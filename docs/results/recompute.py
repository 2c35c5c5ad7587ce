"""Recompute docs/results from its export alone: every run's value, every headline finding
(the test statistic, p, Holm's p, A12 and A12 at the start) and what the guard on seconds
cut, then compare with findings.csv. Exit status 1 on any difference.

    python docs/results/recompute.py docs/results
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from softevo.analysis.rank_tests import holm, jonckheere_terpstra, mann_whitney
from softevo.evolution.stats import vargha_delaney as _vargha_delaney


def vargha_delaney(a: np.ndarray, b: np.ndarray) -> float:
    """A12, NaN where a side has no run (a transition not yet past its switch)."""
    return _vargha_delaney(a, b) if len(a) and len(b) else math.nan

TRENDS = (  # (question start, world, metric, levels in the order the hypothesis says values rise)
    ("land distance rises", "land", "distance", ("S2", "S3", "S4", "S5")),
    ("water distance falls", "water", "distance", ("S5", "S4", "S3", "S2", "S1")),
    ("land frequency falls", "land", "frequency", ("S5", "S4", "S3", "S2")),
    ("water frequency rises", "water", "frequency", ("S1", "S2", "S3", "S4", "S5")),
)


def load(export: Path):
    runs = pd.read_csv(export / "runs.csv")
    evaluations = pd.read_csv(export / "individuals.csv")
    members = pd.read_csv(export / "populations.csv")
    return runs, evaluations, members


def population_values(runs, evaluations, members) -> pd.DataFrame:
    """Per run and generation: the best distance and mean |frequency| of its population, each
    member read at its latest evaluation up to that generation (a member re-evaluated at a
    switch counts in its new world)."""
    latest = evaluations.sort_values("generation").rename(columns={"generation": "evaluated_at"})
    joined = members.merge(latest, on=["run_id", "individual_id"])
    joined = joined[joined["evaluated_at"] <= joined["generation"]]
    joined = joined.sort_values("evaluated_at").groupby(["run_id", "generation", "individual_id"]).last()
    joined = joined.reset_index()
    joined["frequency"] = joined["frequency"].abs()
    values = joined.groupby(["run_id", "generation"]).agg(distance=("distance", "max"),
                                                         frequency=("frequency", "mean"))
    return values.reset_index().merge(runs[["run_id", "treatment"]], on="run_id")


def values_of(values, treatment: str, generation: int, metric: str) -> np.ndarray:
    rows = values[(values["treatment"] == treatment) & (values["generation"] == generation)]
    return rows.sort_values("run_id")[metric].to_numpy(float)


def recompute(export: Path) -> list[dict]:
    runs, evaluations, members = load(export)
    values = population_values(runs, evaluations, members)
    rows = []
    for question, world, metric, levels in TRENDS:
        names = [f"{world} {level}" for level in levels]
        last = int(values[values["treatment"].isin(names)].groupby("run_id")["generation"].max().min())
        final = [values_of(values, n, last, metric) for n in names]
        start = [values_of(values, n, 0, metric) for n in names]
        test = jonckheere_terpstra(final)
        rows.append({"question": question, "statistic": test.statistic, "p": test.p,
                     "a12": vargha_delaney(final[-1], final[0]),
                     "a12_generation0": vargha_delaney(start[-1], start[0])})
    for _, run in runs.drop_duplicates("treatment").iterrows():
        if pd.isna(run["switch_at"]):
            continue
        mine = values[values["treatment"] == run["treatment"]]
        switch, end = int(run["switch_at"]), int(mine.groupby("run_id")["generation"].max().min())
        final_world = run["environment_schedule"].split(",")[-1].split(":")[0]
        control = f"{final_world} {run['treatment'].split()[-1]}"
        for how, control_at in (("equal total generations", end), ("equal time", end - switch)):
            a = values_of(values, run["treatment"], end, "distance")
            b = values_of(values, control, control_at, "distance")
            a0 = values_of(values, run["treatment"], switch, "distance")
            b0 = values_of(values, control, 0, "distance")
            test = mann_whitney(a, b)
            print(f"means: {run['treatment']} at {end} {a.mean():.3g} vs {control} at {control_at} "
                  f"{b.mean():.3g}; on arrival at {switch} {a0.mean():.3g} vs at 0 {b0.mean():.3g}")
            rows.append({"question": f"{run['treatment']} vs {control}, {how}", "statistic": test.statistic,
                         "p": test.p, "a12": vargha_delaney(a, b), "a12_generation0": vargha_delaney(a0, b0)})
    headline = [r for r in rows if "equal time" not in r["question"]]
    for family in (headline, [r for r in rows if "equal time" in r["question"]]):
        for row, p in zip(family, holm([r["p"] for r in family]), strict=True):
            row["p_holm"] = p
    return rows


def gains(export: Path) -> list[dict]:
    """Secondary: is the stiffness trend in distance evolved, or already in random robots? The
    same one-sided trend test on each run's gain (final best distance minus its generation
    0's), and the treatments' means the README quotes."""
    runs, evaluations, members = load(export)
    values = population_values(runs, evaluations, members)
    rows = []
    for question, world, metric, levels in TRENDS[:2]:
        names = [f"{world} {level}" for level in levels]
        last = int(values[values["treatment"].isin(names)].groupby("run_id")["generation"].max().min())
        gain = [values_of(values, n, last, metric) - values_of(values, n, 0, metric) for n in names]
        test = jonckheere_terpstra(gain)
        rows.append({"question": f"{question} (gain from generation 0 to {last})",
                     "statistic": test.statistic, "p": test.p, "a12": vargha_delaney(gain[-1], gain[0]),
                     "gains": ", ".join(f"{n} {g.mean():.3g}" for n, g in zip(names, gain, strict=True))})
    return rows


def treatment_means(export: Path) -> pd.DataFrame:
    """Per treatment at its final generation and at 0: mean best distance and population
    frequency over runs (the README's summary)."""
    runs, evaluations, members = load(export)
    values = population_values(runs, evaluations, members)
    last = values.groupby("run_id")["generation"].transform("max")
    end = values[values["generation"] == last].groupby("treatment", sort=False)[["distance", "frequency"]].mean()
    start = values[values["generation"] == 0].groupby("treatment", sort=False)[["distance", "frequency"]].mean()
    return end.merge(start, left_index=True, right_index=True, suffixes=("", "_generation0"))


def per_second(export: Path) -> pd.Series:
    """Per treatment, the mean over runs of the final best robot's distance per second: its
    distance over its evaluation's seconds after settling (cycles / frequency, at most the
    guard), as summary.csv's ``distance_per_second``."""
    runs, evaluations, members = load(export)
    latest = evaluations.rename(columns={"generation": "evaluated_at"})
    final = members[members["generation"] == members.groupby("run_id")["generation"].transform("max")]
    joined = final.merge(latest, on=["run_id", "individual_id"])
    joined = joined[joined["evaluated_at"] <= joined["generation"]].sort_values("evaluated_at")
    joined = joined.groupby(["run_id", "individual_id"]).last().reset_index()
    best = joined.loc[joined.groupby("run_id")["distance"].idxmax()].merge(runs, on="run_id")
    seconds = np.minimum(best["cycles"] / best["frequency"].abs(), best["max_seconds"])
    return (best["distance"] / seconds).groupby(best["treatment"], sort=False).mean()


def guard(export: Path) -> tuple[int, int, float]:
    """(evaluations the guard on seconds cut, evaluations, the highest frequency)."""
    runs, evaluations, _ = load(export)
    merged = evaluations.merge(runs[["run_id", "cycles", "max_seconds"]], on="run_id")
    frequency = merged["frequency"].abs()
    cut = (merged["cycles"] / frequency > merged["max_seconds"]) & merged["frequency"].notna()
    return int(cut.sum()), len(merged), float(frequency.max())


SENSITIVITY_CONTRASTS = (  # sensitivity.py's: (measure, the level put higher, the one put lower)
    ("distance", "land S4", "land S2"),
    ("distance", "water S1", "water S4"),
    ("frequency", "land S2", "land S4"),
    ("frequency", "water S4", "water S1"),
)


def sensitivity(results: Path) -> int:
    """sensitivity.csv's A12s and means recomputed from the exports in sensitivity/MAPPING/;
    the number of values that differ."""
    table = pd.read_csv(results / "sensitivity.csv")
    differ = 0
    for mapping in table["mapping"].unique():
        runs, evaluations, members = load(results / "sensitivity" / mapping)
        values = population_values(runs, evaluations, members)
        last = int(values.groupby("run_id")["generation"].max().min())
        stored = table[table["mapping"] == mapping].reset_index(drop=True)
        for k, (measure, high, low) in enumerate(SENSITIVITY_CONTRASTS):
            a, b = values_of(values, high, last, measure), values_of(values, low, last, measure)
            a0, b0 = values_of(values, high, 0, measure), values_of(values, low, 0, measure)
            for key, value in (("a12", vargha_delaney(a, b)), ("a12_generation0", vargha_delaney(a0, b0)),
                               ("mean_high", a.mean()), ("mean_low", b.mean())):
                differ += int(not math.isclose(value, float(stored.loc[k, key]), rel_tol=1e-3))
    print(f"sensitivity.csv: {4 * len(SENSITIVITY_CONTRASTS) * table['mapping'].nunique() - differ} of "
          f"{4 * len(SENSITIVITY_CONTRASTS) * table['mapping'].nunique()} values recomputed from sensitivity/")
    return differ


def knees(results: Path) -> int:
    """pilot/knee.csv's knees recomputed from pilot/export (knee.py's rule); the number that differ."""
    from knee import knee  # docs/results/knee.py, beside this script

    table = pd.read_csv(results / "pilot" / "knee.csv")
    values = population_values(*load(results / "pilot" / "export"))
    differ = 0
    for (treatment, run_id), run in values.groupby(["treatment", "run_id"]):
        repetition = sorted(values.loc[values["treatment"] == treatment, "run_id"].unique()).index(run_id)
        at, ninety = knee(run["generation"].to_numpy(float), run["distance"].to_numpy(float))
        row = table[(table["treatment"] == treatment) & (table["curve"] == f"run {repetition}")].iloc[0]
        differ += int(at != row["knee"]) + int(ninety != row["gain_90"])
    checked = 2 * int(table["curve"].str.startswith("run ").sum())  # a knee and a 90% generation per run
    print(f"pilot/knee.csv: {checked - differ} of {checked} per-run values recomputed from pilot/export")
    return differ


def main(results: Path) -> int:
    findings = pd.read_csv(results / "findings.csv")
    rows = recompute(results / "export")
    status = 0
    for row in rows:
        match = findings[findings["question"].str.startswith(row["question"])]
        if len(match) != 1:
            print(f"MISSING {row['question']}")
            status = 1
            continue
        stored = match.iloc[0]
        for key in ("statistic", "p", "p_holm", "a12", "a12_generation0"):
            both_nan = math.isnan(float(stored[key])) and math.isnan(float(row[key]))
            same = both_nan or math.isclose(float(stored[key]), float(row[key]), rel_tol=1e-6, abs_tol=1e-12)
            status |= int(not same)
            print(f"{'ok  ' if same else 'DIFF'} {row['question'][:60]:60s} {key:16s} "
                  f"{row[key]:.6g} (findings.csv {float(stored[key]):.6g})")
    for row in gains(results / "export"):
        print(f"secondary: {row['question']}: J {row['statistic']:g}, one-sided p {row['p']:.3g}, "
              f"A12 of the gains {row['a12']:.2f}; mean gains {row['gains']}")
    print(treatment_means(results / "export").to_string(float_format=lambda v: f"{v:.3g}"))
    speeds = per_second(results / "export")
    print("best robot's distance per second: " + ", ".join(f"{t} {v:.3g}" for t, v in speeds.items()))
    cut, total, highest = guard(results / "export")
    if (results / "pilot" / "export").is_dir():
        status |= int(knees(results) > 0)
    if (results / "sensitivity").is_dir():
        status |= int(sensitivity(results) > 0)
    print(f"the guard on seconds cut {cut} of {total} evaluations ({100 * cut / total:.2f}%); "
          f"the highest frequency evaluated: {highest:.4g} Hz")
    return status


if __name__ == "__main__":
    sys.exit(main(Path(sys.argv[1])))
