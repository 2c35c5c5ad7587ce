"""Seed-matched AFPO vs Pareto per treatment: best distance at generation 9, one value per run,
the report's paired test (``analysis.stats_tables.compare_paired``: Wilcoxon signed-rank),
its paired A12 and Bonferroni over the treatments compared.

Usage: python docs/results/afpo/compare.py STUDY_DB_URL AFPO_DB_URL  (SQLAlchemy URLs of
``softevo experiment paper --scale study`` and of its AFPO variant, docs/results/README.md)
"""

import sys

import pandas as pd

from softevo import load_experiment
from softevo.analysis.stats_tables import compare_paired, paired_a12
from softevo.evolution.stats import bonferroni

TREATMENTS = ("land S3", "water S3", "land-water S3", "water-land S3")
GENERATION = 9


def best_by_seed(db: str) -> pd.DataFrame:
    """Best distance at ``GENERATION``, one row per run: treatment, seed, best_distance."""
    data = load_experiment(db, generations=[GENERATION])
    values = data.run_values(GENERATION).merge(data.runs[["run_id", "seed"]], on="run_id")
    return values[["treatment", "seed", "best_distance"]]


def main() -> None:
    pareto, afpo = best_by_seed(sys.argv[1]), best_by_seed(sys.argv[2])
    pairs = afpo.merge(pareto, on=["treatment", "seed"], suffixes=("_afpo", "_pareto"))
    rows = []
    for name in TREATMENTS:
        pair = pairs[pairs["treatment"] == name]
        x, y = pair["best_distance_afpo"].to_numpy(), pair["best_distance_pareto"].to_numpy()
        rows.append((name, x.mean(), y.mean(), len(pair), compare_paired(x, y)[1], paired_a12(x, y)))
    corrected = bonferroni([row[4] for row in rows])
    print("| treatment | AFPO mean | Pareto mean | n pairs | Wilcoxon p | p_B "
          "| A12 (AFPO vs Pareto, paired) |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: |")
    for (name, a, b, n, p, a12), p_b in zip(rows, corrected, strict=True):
        print(f"| {name} | {a:.3g} | {b:.3g} | {n} | {p:.2g} | {p_b:.2g} | {a12:.2f} |")


if __name__ == "__main__":
    main()
