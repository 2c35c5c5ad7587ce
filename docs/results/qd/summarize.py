"""The quality-diversity study (docs/results/qd/README.md): what MAP-Elites' archives hold on
land, in water and across the two transitions, from a stored experiment.

    python docs/results/qd/summarize.py sqlite:///qd.db qd-pilot docs/results/qd

Writes, into the folder given:
- ``runs.csv``: one row per run (the unit): treatment, seed, the worlds, coverage, QD score
  and cells filled of the archive after generation 0 (random bodies: the baseline) and after
  the last generation (in the world of that generation);
- ``cells.csv``: per treatment and cell of its final archives, the runs that fill it and the
  mean distance of their elites (which niches each world fills);
- ``kept.csv``: for each transition run, the cells its first world's archive held at the
  switch (the last generation in the first world) and how many of them its second world's
  archive holds at the end (which it keeps);
- ``test.csv``: the declared primary comparison, final coverage land S3 against water S3
  (two-sided exact Mann-Whitney), with the smallest p-value its sample sizes allow and the
  verdict, from code;
- ``archives.png``: each treatment's final archives, every cell's share of runs filling it
  and its mean elite distance.
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from scipy.stats import mannwhitneyu  # noqa: E402
from sqlalchemy import select  # noqa: E402

from softevo.service.storage import open_database  # noqa: E402
from softevo.service.storage.archive import run_archive, run_worlds, world_at  # noqa: E402
from softevo.service.storage.models import ExperimentRow, RunRow, TreatmentRow  # noqa: E402

ALPHA = 0.05
PRIMARY = ("land S3", "water S3")


def stored_runs(conn, experiment: str) -> pd.DataFrame:
    runs, treatments, experiments = RunRow.__table__, TreatmentRow.__table__, ExperimentRow.__table__
    query = (select(runs.c.id, runs.c.seed, runs.c.generation, treatments.c.name.label("treatment"),
                    treatments.c.settings)
             .join(treatments, runs.c.treatment_id == treatments.c.id)
             .join(experiments, treatments.c.experiment_id == experiments.c.id)
             .where(experiments.c.name == experiment).order_by(runs.c.id))
    return pd.DataFrame(conn.execute(query).mappings().all())


def summarize(url: str, experiment: str, out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    engine = open_database(url)
    rows, cells, kept, finals = [], [], [], {}
    with engine.connect() as conn:
        runs = stored_runs(conn, experiment)
        for run in runs.itertuples():
            worlds = run_worlds(conn, run.id)
            first = run_archive(conn, run.id, 0)
            last = run_archive(conn, run.id)
            finals[run.id] = last
            rows.append({"run_id": run.id, "treatment": run.treatment, "seed": run.seed,
                         "worlds": "-".join(worlds), "generations": run.generation + 1,
                         "coverage_0": first["coverage"], "qd_score_0": first["qd_score"],
                         "filled_0": first["filled"], "world_last": last["environment"],
                         "coverage": last["coverage"], "qd_score": last["qd_score"],
                         "filled": last["filled"]})
            if len(worlds) > 1:
                switch = next(g for g in range(run.generation + 1)
                              if world_at(conn, run.id, g) != worlds[0]) - 1
                before = {tuple(e["cell"]) for e in run_archive(conn, run.id, switch, worlds[0])["elites"]}
                after = {tuple(e["cell"]) for e in last["elites"]}
                kept.append({"run_id": run.id, "treatment": run.treatment, "first_world": worlds[0],
                             "cells_at_switch": len(before), "cells_at_end": len(after),
                             "kept": len(before & after), "new": len(after - before)})
    engine.dispose()
    table = pd.DataFrame(rows)
    table.to_csv(out / "runs.csv", index=False)
    pd.DataFrame(kept).to_csv(out / "kept.csv", index=False)
    any_archive = next(iter(finals.values()))
    shape = tuple(any_archive["cells"])
    for name, part in table.groupby("treatment", sort=False):
        fill = np.zeros(shape)
        total = np.zeros(shape)
        for run_id in part["run_id"]:
            for elite in finals[run_id]["elites"]:
                fill[tuple(elite["cell"])] += 1
                total[tuple(elite["cell"])] += elite["distance"]
        for index in np.ndindex(shape):
            if fill[index]:
                cells.append({"treatment": name, "cell": ",".join(map(str, index)), "runs": int(fill[index]),
                              "of": len(part), "mean_distance": total[index] / fill[index]})
    pd.DataFrame(cells).to_csv(out / "cells.csv", index=False)
    test(table).to_csv(out / "test.csv", index=False)
    figure(table, finals, shape, any_archive, out / "archives.png")


def test(table: pd.DataFrame) -> pd.DataFrame:
    """The primary comparison and its verdict: with n1 and n2 runs the exact two-sided
    Mann-Whitney test cannot go below 2 / C(n1 + n2, n1); a design whose smallest p is above
    ALPHA cannot detect anything, and says so."""
    a = table[table["treatment"] == PRIMARY[0]]["coverage"].to_numpy()
    b = table[table["treatment"] == PRIMARY[1]]["coverage"].to_numpy()
    from math import comb

    smallest = min(1.0, 2 / comb(len(a) + len(b), len(a)))
    p = float(mannwhitneyu(a, b, alternative="two-sided", method="exact").pvalue)
    if smallest > ALPHA:
        verdict = f"not decidable at this scale (n = {len(a)}, {len(b)}: the smallest p is {smallest:.3g})"
    else:
        verdict = "differs" if p < ALPHA else "no difference detected"
    return pd.DataFrame([{"measure": "final coverage", "a": PRIMARY[0], "b": PRIMARY[1], "n_a": len(a),
                          "n_b": len(b), "median_a": float(np.median(a)), "median_b": float(np.median(b)),
                          "p": p, "smallest_p": smallest, "verdict": verdict}])


def figure(table, finals, shape, grid, path: Path) -> None:
    names = list(dict.fromkeys(table["treatment"]))
    fig, axes = plt.subplots(2, len(names), figsize=(3.2 * len(names), 6.2), squeeze=False)
    (x0, x1), (y0, y1) = grid["bounds"][0], grid["bounds"][1]
    for k, name in enumerate(names):
        ids = table[table["treatment"] == name]["run_id"]
        fill, dist = np.zeros(shape), np.zeros(shape)
        for run_id in ids:
            for elite in finals[run_id]["elites"]:
                fill[tuple(elite["cell"])] += 1
                dist[tuple(elite["cell"])] += elite["distance"]
        share = fill / len(ids)
        mean = np.where(fill > 0, dist / np.maximum(fill, 1), np.nan)
        world = table[table["treatment"] == name]["world_last"].iloc[0]
        for row, (values, title, cmap) in enumerate(((share, "share of runs filling", "Blues"),
                                                     (mean, "mean elite distance", "viridis"))):
            ax = axes[row, k]
            image = ax.imshow(values.T, origin="lower", extent=(x0, x1, y0, y1), aspect="auto", cmap=cmap,
                              vmin=0, vmax=1 if row == 0 else None)
            ax.set_title(f"{name} ({world})\n{title}", fontsize=8)
            ax.set_xlabel(grid["measures"][0], fontsize=8)
            ax.set_ylabel(grid["measures"][1], fontsize=8)
            fig.colorbar(image, ax=ax, fraction=0.046)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    summarize(sys.argv[1], sys.argv[2], Path(sys.argv[3]))
