"""The knee of the pilot's static S3 fitness curves (docs/results/README.md): for each run
and for the mean curve of each treatment, the generation of the knee by the chord rule
(kneedle, Satopaa et al. 2011: the generation farthest above the straight line from the
first to the last generation, both axes scaled to 0..1) and the first generation at 90%
of the run's gain.

    python docs/results/knee.py sqlite:///pilot.db knee-pilot > docs/results/pilot/knee.csv
"""

from __future__ import annotations

import sys

import numpy as np
import pandas as pd

import softevo


def knee(generations: np.ndarray, best: np.ndarray) -> tuple[int, int]:
    """(the chord rule's knee, the first generation at 90% of the gain)."""
    x = (generations - generations[0]) / (generations[-1] - generations[0])
    gain = best[-1] - best[0]
    y = (best - best[0]) / gain if gain > 0 else np.zeros_like(best)
    return int(generations[np.argmax(y - x)]), int(generations[np.argmax(y >= 0.9)])


def rows(db: str, experiment: str):
    curves = softevo.load_experiment(db, experiment).generations
    for (treatment, repetition), run in curves.groupby(["treatment", "repetition"]):
        run = run.sort_values("generation")
        at, ninety = knee(run["generation"].to_numpy(float), run["best_distance"].to_numpy(float))
        yield {"treatment": treatment, "curve": f"run {repetition}", "knee": at, "gain_90": ninety,
               "best_generation0": run["best_distance"].iloc[0], "best_final": run["best_distance"].iloc[-1]}
    for treatment, runs in curves.groupby("treatment"):
        mean = runs.groupby("generation")["best_distance"].mean()
        at, ninety = knee(mean.index.to_numpy(float), mean.to_numpy(float))
        yield {"treatment": treatment, "curve": "mean over runs", "knee": at, "gain_90": ninety,
               "best_generation0": mean.iloc[0], "best_final": mean.iloc[-1]}


if __name__ == "__main__":
    pd.DataFrame(list(rows(sys.argv[1], sys.argv[2]))).to_csv(sys.stdout, index=False, float_format="%.4g")
