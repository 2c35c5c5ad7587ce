"""The 2x2 sensitivity of the frequency mapping (docs/results/README.md): for each mapping
(bounded at 4 Hz or not x a negative f run at |f| or invalid), on the same seeds, each
contrast of the stiffness trends the pilot holds, as A12 of one value per run at the last
generation (best distance; the population's mean frequency), beside generation 0.

    python docs/results/sensitivity.py sqlite:///sensitivity.db > docs/results/sensitivity.csv
"""

from __future__ import annotations

import sys

import pandas as pd

import softevo
from softevo.evolution.stats import vargha_delaney as a12

MAPPINGS = ("evosoro-bounded", "evosoro", "evosoro-bounded-positive", "evosoro-positive")
# (question, measure, the treatment the hypothesis puts higher, the one it puts lower)
CONTRASTS = (
    ("land distance rises with stiffness", "best_distance", "land S4", "land S2"),
    ("water distance falls with stiffness", "best_distance", "water S1", "water S4"),
    ("land frequency falls with stiffness", "frequency", "land S2", "land S4"),
    ("water frequency rises with stiffness", "frequency", "water S4", "water S1"),
)


def rows(db: str):
    for mapping in MAPPINGS:
        data = softevo.load_experiment(db, f"sensitivity {mapping}")
        last = int(data.runs["generation"].min())
        end, start = data.run_values(last), data.run_values(0)
        for question, measure, high, low in CONTRASTS:
            values = {}
            for label, frame in (("end", end), ("gen0", start)):
                a = frame.loc[frame["treatment"] == high, measure].to_numpy()
                b = frame.loc[frame["treatment"] == low, measure].to_numpy()
                values[label] = (a, b)
            (a, b), (a0, b0) = values["end"], values["gen0"]
            yield {"mapping": mapping, "question": question, "measure": measure,
                   "contrast": f"{high} vs {low}", "generation": last, "n": f"{len(a)}+{len(b)}",
                   "mean_high": a.mean(), "mean_low": b.mean(), "a12": a12(a, b),
                   "a12_generation0": a12(a0, b0),
                   "max_frequency": float(end["frequency"].max())}


if __name__ == "__main__":
    pd.DataFrame(list(rows(sys.argv[1]))).to_csv(sys.stdout, index=False, float_format="%.4g")
