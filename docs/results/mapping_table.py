"""The frequencies random robots get under the evosoro mappings (docs/algorithm.md's table).

    python docs/results/mapping_table.py > docs/results/mapping_table.csv

For each workspace (5^3, 7^3) and each mapping (``evosoro-logistic``, the presets';
``evosoro-bounded``, the bipolar output clipped at 4 Hz; ``evosoro``, the bipolar output as the
formula gives it), ``N`` random viable genomes are drawn, viability judged under that mapping's
own encoding (``EncodingConfig(workspace, control_mapping, body_rule="evosoro")``), and the
frequency of each developed robot is summarised: median, 5% and 95% quantiles, the share
exactly at 4.0 Hz (the bound), above 4 Hz and below 0.5 Hz.

Every mapping of a workspace starts from the same seed, so the three draw the same genomes
wherever viability agrees (it differs only for a frequency with no period): the rows compare
one sample read three ways. Deterministic: the seed is fixed here. Seconds on one core.
"""

from __future__ import annotations

import csv
import sys
import time

import numpy as np

from softevo.evolution.genotype import EncodingConfig, is_viable, random_viable

SEED = 20261207
N = 500
WORKSPACES = ((5, 5, 5), (7, 7, 7))
MAPPINGS = ("evosoro-logistic", "evosoro-bounded", "evosoro")
BOUND_HZ = 4.0
SLOW_HZ = 0.5
COLUMNS = ("workspace", "mapping", "n", "median_hz", "q05_hz", "q95_hz", "share_at_4hz", "share_above_4hz",
           "share_below_0_5hz")


def frequencies(workspace: tuple[int, int, int], mapping: str, n: int = N) -> np.ndarray:
    """Frequencies (Hz) of ``n`` random viable robots of ``mapping`` on ``workspace``:
    ``random_viable`` is ``random_viable_genotype`` with the phenotype it judged; a draw that
    found no viable genome in its tries is left out and another taken."""
    config = EncodingConfig(workspace=workspace, control_mapping=mapping, body_rule="evosoro")
    rng = np.random.default_rng([SEED, workspace[0]])
    found: list[float] = []
    while len(found) < n:
        _, phenotype = random_viable(rng, config)
        if is_viable(phenotype, config):
            found.append(float(phenotype.frequency))
    return np.asarray(found)


def summary(workspace: tuple[int, int, int], mapping: str, hz: np.ndarray) -> dict[str, object]:
    q05, median, q95 = np.quantile(hz, [0.05, 0.5, 0.95])
    return {
        "workspace": "x".join(map(str, workspace)),
        "mapping": mapping,
        "n": len(hz),
        "median_hz": f"{median:.3f}",
        "q05_hz": f"{q05:.3f}",
        "q95_hz": f"{q95:.3f}",
        "share_at_4hz": f"{np.mean(hz == BOUND_HZ):.3f}",
        "share_above_4hz": f"{np.mean(hz > BOUND_HZ):.3f}",
        "share_below_0_5hz": f"{np.mean(hz < SLOW_HZ):.3f}",
    }


def main() -> None:
    writer = csv.DictWriter(sys.stdout, fieldnames=COLUMNS, lineterminator="\n")
    writer.writeheader()
    for workspace in WORKSPACES:
        for mapping in MAPPINGS:
            started = time.monotonic()
            writer.writerow(summary(workspace, mapping, frequencies(workspace, mapping)))
            sys.stdout.flush()
            print(f"{workspace} {mapping}: {time.monotonic() - started:.0f} s", file=sys.stderr)


if __name__ == "__main__":
    main()
