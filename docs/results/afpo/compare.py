"""Seed-matched AFPO vs Pareto per treatment: best distance at generation 9, one value per run,
Wilcoxon signed-rank (exact), A12.

Usage: python docs/results/afpo/compare.py STUDY.db AFPO.db  (the SQLite files of
``softevo experiment paper --scale study`` and of its AFPO variant, docs/results/README.md)
"""

import sqlite3
import sys

import numpy as np
from scipy import stats

TREATMENTS = ("land S3", "water S3", "land-water S3", "water-land S3")


def values(db: str) -> dict[str, dict[int, float]]:
    """{treatment: {seed: best distance at generation 9}}."""
    query = """select t.name, r.seed, g.best_distance from generations g
               join runs r on r.id = g.run_id join treatments t on t.id = r.treatment_id
               where g.generation = 9"""
    out: dict[str, dict[int, float]] = {}
    with sqlite3.connect(db) as conn:
        for name, seed, best in conn.execute(query):
            out.setdefault(name, {})[seed] = best
    return out


def main() -> None:
    pareto, afpo = values(sys.argv[1]), values(sys.argv[2])
    print("| treatment | AFPO mean | Pareto mean | n pairs | Wilcoxon p | Bonferroni (4) "
          "| A12 (AFPO vs Pareto) |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: |")
    for name in TREATMENTS:
        seeds = sorted(set(pareto[name]) & set(afpo[name]))
        x = np.array([afpo[name][s] for s in seeds])
        y = np.array([pareto[name][s] for s in seeds])
        p = stats.wilcoxon(x, y, method="exact").pvalue
        a12 = (x[:, None] > y[None, :]).mean() + 0.5 * (x[:, None] == y[None, :]).mean()
        print(f"| {name} | {x.mean():.3g} | {y.mean():.3g} | {len(seeds)} | {p:.2g} | "
              f"{min(1.0, 4 * p):.2g} | {a12:.2f} |")


if __name__ == "__main__":
    main()
