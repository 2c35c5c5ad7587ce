"""Exaptation across environment transitions, per run: which founders' lines survived the
switch and which pre-switch traits the survivors carried.

Input (``ExaptationData``, built by ``service.reports.report.exaptation_data`` from
``service.storage.exaptation``; see ``docs/sql.md`` for the definitions):

- ``runs``: one row per transition run: run_id, switch_at, switch_over, arrival, generation
  (last stored), founders, founders_surviving, final_population, from_founders, lines;
- ``founders``: one row per founder (the population kept at ``switch_at - 1``): run_id,
  founder_id, lines (final members descending from it), front_lines, surviving (lines > 0)
  and its traits at birth (``evolution.traits.along_lines()``);
- ``lines``: one row per surviving line (founder, final member): run_id, founder_id,
  individual_id and, per trait, ``<trait>_founder``, ``<trait>_switch``, ``<trait>_end``,
  ``<trait>_changed`` (birth generation of the first change, NaN: never).

Statistics are per run (each run one observation), never pooled over individuals.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from softevo.analysis import figures as fig
from softevo.analysis.data import ExperimentData
from softevo.evolution import traits

NAME = "exaptation"  # its title is figures.TITLES[NAME]


@dataclass(frozen=True)
class ExaptationData:
    runs: pd.DataFrame
    founders: pd.DataFrame
    lines: pd.DataFrame

    @property
    def empty(self) -> bool:
        return self.runs.empty


def run_statistics(data: ExperimentData, exaptation: ExaptationData) -> pd.DataFrame:
    """One row per transition run: treatment, repetition, founders, founders_surviving,
    surviving_share, final_from_founders (share of the final population descending from a
    founder), lines, and per trait ``<trait>_survivors`` (mean at birth over the founders
    with a surviving line), ``<trait>_all`` (over all founders) and ``<trait>_shift``
    (their difference: what selection across the switch favoured)."""
    labels = data.runs[["run_id", "treatment", "repetition"]]
    rows = []
    for run in exaptation.runs.itertuples(index=False):
        founders = exaptation.founders[exaptation.founders["run_id"] == run.run_id]
        survivors = founders[founders["surviving"]]
        row = {
            "run_id": run.run_id,
            "founders": run.founders,
            "founders_surviving": run.founders_surviving,
            "surviving_share": run.founders_surviving / run.founders if run.founders else np.nan,
            "final_from_founders": run.from_founders / run.final_population
            if run.final_population
            else np.nan,
            "lines": run.lines,
        }
        for trait in traits.along_lines():
            kept = pd.to_numeric(survivors[trait], errors="coerce").mean()
            every = pd.to_numeric(founders[trait], errors="coerce").mean()
            row |= {f"{trait}_survivors": kept, f"{trait}_all": every, f"{trait}_shift": kept - every}
        rows.append(row)
    table = pd.DataFrame(rows)
    if table.empty:
        return table
    return labels.merge(table, on="run_id").sort_values(["treatment", "repetition"]).reset_index(drop=True)


def treatment_summary(stats: pd.DataFrame) -> pd.DataFrame:
    """Per treatment, the mean over its runs of the per-run statistics shown in the report."""
    if stats.empty:
        return stats
    columns = ["founders_surviving", "surviving_share", "final_from_founders"] + [
        f"{trait}_shift" for trait in traits.along_lines()
    ]
    summary = stats.groupby("treatment", sort=False)[columns].mean().reset_index()
    summary.insert(1, "runs", stats.groupby("treatment", sort=False).size().to_numpy())
    return summary


def exaptation_figure(
    data: ExperimentData, exaptation: ExaptationData, stats: pd.DataFrame, out_dir: Path
) -> fig.FigureFile | None:
    """Left: per run, founders and founders whose lines reach the end. Right: each surviving
    line's active share at the founder, at the switch (arrival) and at the end, per
    treatment. None without a transition run."""
    if exaptation.empty or stats.empty:
        return None
    colors = fig.treatment_colors(data.treatments)
    figure, (counts, shares) = plt.subplots(
        1, 2, figsize=fig.figure_size(NAME, len(data.treatments)), dpi=fig.DPI, layout="constrained"
    )
    x = np.arange(len(stats))
    counts.bar(x - 0.2, stats["founders"], 0.4, color="#cfd6e0", label="founders (kept at the switch)")
    counts.bar(
        x + 0.2,
        stats["founders_surviving"],
        0.4,
        color=[colors[t] for t in stats["treatment"]],
        label="founders with a line to the end",
    )
    counts.set_xticks(
        x, [f"{t}\nrep {r}" for t, r in zip(stats["treatment"], stats["repetition"], strict=True)], fontsize=8
    )
    counts.set(ylabel="founders", title="founders surviving the switch, per run")
    counts.legend(fontsize=8)
    counts.grid(axis="y", alpha=0.3)
    treatment_of = dict(zip(stats["run_id"], stats["treatment"], strict=True))
    lines = exaptation.lines
    for row in lines.itertuples(index=False):
        values = [getattr(row, f"active_share_{stage}") for stage in ("founder", "switch", "end")]
        shares.plot([0, 1, 2], values, "-o", color=colors[treatment_of[row.run_id]], alpha=0.5, markersize=3)
    for name in dict.fromkeys(treatment_of.values()):
        shares.plot([], [], "-o", color=colors[name], label=name)
    shares.set_xticks([0, 1, 2], ["founder", "arrival in the new world", "end"])
    shares.set(ylabel=traits.labels()["active_share"], title="active share along each surviving line")
    shares.legend(fontsize=8)
    shares.grid(alpha=0.3)
    caption = (
        "Left: per transition run, the founders (the population kept just before the switch) and "
        "those whose lines reach the last generation. Right: each surviving line's active share "
        "at its founder, at the first generation wholly in the new world and at the end."
    )
    return fig.save(figure, out_dir, NAME, caption)
