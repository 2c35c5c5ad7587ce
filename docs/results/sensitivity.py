"""The sensitivity of the frequency findings to the frequency mapping (docs/results/README.md):
for each reading of the scripts' formula (the presets' logistic one, the bipolar one clipped
at 4 Hz, the literal unbounded one), at the pilot scale on seeds of its own, each frequency
contrast of the stiffness trends as A12 of one value per run at the last generation: the
change of the population's mean frequency from generation 0 (the primary measure) and its
final level, beside the level's A12 at generation 0.

    python docs/results/sensitivity.py sqlite:///sensitivity.db > docs/results/sensitivity.csv
"""

from __future__ import annotations

import sys

import pandas as pd

import softevo
from softevo.analysis.findings import run_values
from softevo.evolution.stats import vargha_delaney as a12

MAPPINGS = ("evosoro-logistic", "evosoro-bounded", "evosoro")
# (question, the treatment the hypothesis puts higher, the one it puts lower)
CONTRASTS = (
    ("land frequency falls with stiffness", "land S2", "land S4"),
    ("water frequency rises with stiffness", "water S4", "water S1"),
)
MEASURES = ("frequency_change", "frequency")


def rows(db: str):
    for mapping in MAPPINGS:
        data = softevo.load_experiment(db, f"sensitivity {mapping}")
        last = int(data.runs["generation"].min())
        seeds = sorted(int(s) for s in data.runs["seed"])
        for question, high, low in CONTRASTS:
            a0, b0 = (run_values(data, name, 0, "frequency") for name in (high, low))
            for measure in MEASURES:
                a, b = (run_values(data, name, last, measure) for name in (high, low))
                yield {"mapping": mapping, "question": question, "measure": measure,
                       "contrast": f"{high} vs {low}", "generation": last, "n": f"{len(a)}+{len(b)}",
                       "seeds": f"{seeds[0]}..{seeds[-1]}", "mean_high": a.mean(), "mean_low": b.mean(),
                       "a12": a12(a, b), "a12_generation0": a12(a0, b0),
                       "max_frequency": float(data.evaluations["frequency"].abs().max())}


if __name__ == "__main__":
    pd.DataFrame(list(rows(sys.argv[1]))).to_csv(sys.stdout, index=False, float_format="%.4g")
